"""Figures of a calibration: fitted against measured curves with confidence bands, and
residuals, one panel pair per curve. Figures are built without pyplot (no global state)."""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure

from ._result import Z_95, FitResult


def band_grid(result: FitResult) -> np.ndarray:
    """Deflections ``[C, P]`` [m] for smooth model curves: ``P`` evenly spaced points from 0
    to each curve's largest measured deflection (the fitted batch's shape, so drawing the
    band reuses the fit's compiled function)."""
    batch = result.problem.batch
    width = batch.deflection.shape[1]
    grid = []
    for curve in result.problem.data:
        top = float(curve.deflection[np.argmax(np.abs(curve.deflection))])
        grid.append(np.linspace(top / width, top, width))
    return np.asarray(grid)


def fit_figure(result: FitResult, title: str | None = None) -> Figure:
    """Per curve: measured points, the fitted model with its 95 % confidence band (delta
    method) and, below, the residuals (model - measured) with the +-2 sigma noise band."""
    data = result.problem.data
    count = len(data)
    columns = min(3, count)
    rows = math.ceil(count / columns)
    figure = Figure(figsize=(4.6 * columns, 4.4 * rows), layout="constrained")
    grid = figure.add_gridspec(2 * rows, columns, height_ratios=[3, 1.3] * rows)
    batch = result.problem.batch
    deflection = band_grid(result)
    force, sd = result.predict(batch.pressure, batch.radius, batch.length, deflection)
    for c, curve in enumerate(data):
        row, col = divmod(c, columns)
        top = figure.add_subplot(grid[2 * row, col])
        bottom = figure.add_subplot(grid[2 * row + 1, col], sharex=top)
        u_mm = deflection[c] * 1e3
        finite = np.isfinite(sd[c])
        top.fill_between(u_mm[finite], (force[c] - Z_95 * sd[c])[finite],
                         (force[c] + Z_95 * sd[c])[finite], color="C0", alpha=0.25, lw=0,
                         label="95 % band")
        top.plot(u_mm, force[c], color="C0", lw=1.6, label="model")
        top.plot(curve.deflection * 1e3, curve.force, "o", ms=3.5, color="k",
                 label="measured")
        top.set_title(f"{curve.name}: {curve.pressure / 1e5:.3g} bar, r = "
                      f"{curve.radius * 1e3:.3g} mm, L = {curve.length:.3g} m", fontsize=9)
        top.set_ylabel("tip force [N]")
        top.grid(alpha=0.3)
        if c == 0:
            top.legend(fontsize=8, loc="lower right")
        residual = result.force[c] - curve.force
        bottom.axhspan(-2 * result.noise, 2 * result.noise, color="0.85", lw=0,
                       label="+-2 noise sd")
        bottom.axhline(0.0, color="0.4", lw=0.8)
        bottom.plot(curve.deflection * 1e3, residual, "o", ms=3, color="C3")
        bottom.set_xlabel("tip deflection [mm]")
        bottom.set_ylabel("model - meas. [N]", fontsize=8)
        bottom.grid(alpha=0.3)
    figure.suptitle(title or f"fit to {data.source}: RMSE {result.rmse:.3g} N "
                             f"(noise {result.noise:.3g} N)", fontsize=11)
    return figure


def prediction_figure(deflection_mm, force, sd, label: str) -> Figure:
    """One predicted curve with its 95 % band."""
    figure = Figure(figsize=(6, 4.2), layout="constrained")
    axes = figure.add_subplot()
    finite = np.isfinite(sd)
    axes.fill_between(deflection_mm[finite], (force - Z_95 * sd)[finite],
                      (force + Z_95 * sd)[finite], color="C0", alpha=0.25, lw=0,
                      label="95 % band")
    axes.plot(deflection_mm, force, color="C0", lw=1.8, label="fitted model")
    axes.set_xlabel("tip deflection [mm]")
    axes.set_ylabel("tip force [N]")
    axes.set_title(label, fontsize=10)
    axes.grid(alpha=0.3)
    axes.legend()
    return figure
