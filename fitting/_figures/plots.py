"""Figures of a calibration: fitted against measured curves with confidence bands, and
residuals, one panel pair per curve. Figures are built without pyplot (no global state)."""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure

import jaxtube as jt

from .._calibrate.result import Z_95, FitResult
from .._data.units import MM_PER_M
from .._diagnose.compare import EXTENT_EDGES, point_table

PA_PER_BAR = jt.unit_factor("pressure", "bar")


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
        u_mm = deflection[c] * MM_PER_M
        finite = np.isfinite(sd[c])
        top.fill_between(u_mm[finite], (force[c] - Z_95 * sd[c])[finite],
                         (force[c] + Z_95 * sd[c])[finite], color="C0", alpha=0.25, lw=0,
                         label="95 % band")
        top.plot(u_mm, force[c], color="C0", lw=1.6, label="model")
        top.plot(curve.deflection * MM_PER_M, curve.force, "o", ms=3.5, color="k",
                 label="measured")
        top.set_title(f"{curve.name}: {curve.pressure / PA_PER_BAR:.3g} bar, r = "
                      f"{curve.radius * MM_PER_M:.3g} mm, L = {curve.length:.3g} m", fontsize=9)
        top.set_ylabel("tip force [N]")
        top.grid(alpha=0.3)
        if c == 0:
            top.legend(fontsize=8, loc="lower right")
        residual = result.force[c] - curve.force
        bottom.axhspan(-2 * result.noise, 2 * result.noise, color="0.85", lw=0,
                       label="+-2 noise sd")
        bottom.axhline(0.0, color="0.4", lw=0.8)
        bottom.plot(curve.deflection * MM_PER_M, residual, "o", ms=3, color="C3")
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


# --------------------------------------------------------------------------------------------
# Diagnosis figures
# --------------------------------------------------------------------------------------------

GROUP_TITLES = {"pressure": "by pressure", "radius": "by radius", "length": "by length",
                "regime": "by worst joint regime (model)",
                "wrinkled_extent": "by how far wrinkling reaches along the tube"}


def where_it_fails_figure(result: FitResult, comparison, title: str) -> Figure:
    """Residuals against deflection for every curve, then grouped by pressure, radius,
    length, the model's regime at each point and the wrinkled extent: each group's points,
    its RMSE (bar) and bias (diamond), against the +-2 sigma noise band."""
    table = point_table(result)
    names = [curve.name for curve in result.problem.data]
    figure = Figure(figsize=(15, 8.4), layout="constrained")
    axes = figure.subplots(2, 3).ravel()
    noise = result.noise
    ax = axes[0]
    for c, name in enumerate(names):
        keep = table["curve"] == c
        order = np.argsort(np.abs(table["deflection"][keep]))
        ax.plot(np.abs(table["deflection"][keep])[order] * MM_PER_M,
                table["residual"][keep][order], "o-", ms=3, lw=0.8, label=name)
    ax.axhspan(-2 * noise, 2 * noise, color="0.88", lw=0)
    ax.axhline(0, color="0.4", lw=0.8)
    ax.set_xlabel("tip deflection [mm]")
    ax.set_ylabel("model - measured [N]")
    ax.set_title("residuals along each curve", fontsize=10)
    ax.legend(fontsize=7, ncol=2)
    for ax, quantity in zip(axes[1:], GROUP_TITLES):
        groups = comparison.groups_of(quantity)
        ax.axhspan(-2 * noise, 2 * noise, color="0.88", lw=0, label="+-2 noise sd")
        ax.axhline(0, color="0.4", lw=0.8)
        for k, group in enumerate(groups):
            if quantity == "wrinkled_extent":
                edges = _extent_bin(table["extent"], group.value)
                keep = edges
            elif quantity == "regime":
                keep = table["regime"] == group.value
            else:
                keep = table[quantity] == group.value
            jitter = (np.random.default_rng(k).random(int(keep.sum())) - 0.5) * 0.3
            ax.plot(k + jitter, table["residual"][keep], "o", ms=2.5, color="C0", alpha=0.6)
            ax.bar(k, group.rmse_N, width=0.55, color="C3", alpha=0.25,
                   label="RMSE" if k == 0 else None)
            ax.plot(k, group.bias_N, "D", color="C3", ms=6, label="bias" if k == 0 else None)
        ax.set_xticks(range(len(groups)), [g.label for g in groups], fontsize=8,
                      rotation=20 if quantity == "wrinkled_extent" else 0)
        ax.set_title(GROUP_TITLES[quantity], fontsize=10)
        ax.set_ylabel("model - measured [N]")
        ax.grid(alpha=0.3, axis="y")
        if quantity == "pressure":
            ax.legend(fontsize=7)
    figure.suptitle(f"{title}: where the model fails (RMSE {comparison.rmse_N:.3g} N, noise "
                    f"{noise:.3g} N). {comparison.verdict.words}", fontsize=9, wrap=True)
    return figure


def _extent_bin(extent: np.ndarray, low: float) -> np.ndarray:
    i = list(EXTENT_EDGES).index(low)
    return (extent >= EXTENT_EDGES[i]) & (extent < EXTENT_EDGES[i + 1])


def draw_ranking(ax, rows, threshold: float, title: str) -> None:
    """On ``ax``: the BIC drop of every candidate's refit (``rows``: ranked
    :class:`fitting.CandidateRanking`, best first; log scale), significant ones green, the
    ``threshold`` dashed, and the score statistic beside each bar."""
    labels = [row.effect for row in rows][::-1]
    drops = [max(-row.delta_bic, 0.1) if math.isfinite(row.delta_bic) else 0.1
             for row in rows][::-1]
    colours = ["C2" if row.significant else "0.6" for row in rows][::-1]
    ax.barh(range(len(rows)), drops, color=colours)
    for k, row in enumerate(rows[::-1]):
        ax.text(drops[k] * 1.1, k, f"S = {row.score_statistic:.3g}", va="center", fontsize=7)
    ax.axvline(threshold, color="k", ls="--", lw=0.8)
    ax.set_xscale("log")
    ax.set_yticks(range(len(rows)), labels, fontsize=8)
    ax.set_xlabel("BIC drop of the refit (green: significant)")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3, axis="x")


def ranking_figure(diagnosis) -> Figure:
    """One panel per ranking (each addition, then the final one), drawn by
    :func:`draw_ranking`."""
    rankings = [(f"step {i + 1}: " + ("none significant, pivots refined" if s.refinement
                                      else f"added {s.added}"), s.candidates)
                for i, s in enumerate(diagnosis.steps)]
    if diagnosis.final_candidates:
        rankings.append(("final: none significant" if diagnosis.stop_reason.startswith("no")
                         else f"final ({diagnosis.stop_reason})", diagnosis.final_candidates))
    count = max(len(rankings), 1)
    figure = Figure(figsize=(5.2 * count, 3.8), layout="constrained")
    axes = np.atleast_1d(figure.subplots(1, count))
    for ax, (title, rows) in zip(axes, rankings):
        draw_ranking(ax, rows, diagnosis.options.bic_threshold, title)
    verdict = ", ".join(diagnosis.verdict) or "nothing missing"
    figure.suptitle(f"candidates ranked; verdict: {verdict}", fontsize=10)
    return figure


def draw_rmse_per_curve(ax, models, noise: float, title: str) -> None:
    """On ``ax``: grouped bars of every curve's RMSE [N] for each ``(label, FitResult)`` of
    ``models`` (fits of the same data), against the ``noise`` [N] (dashed)."""
    names = [curve.name for curve in models[0][1].problem.data]
    width = 0.8 / len(models)
    for k, (label, result) in enumerate(models):
        rmse = [row["rmse_N"] for row in result.curve_errors()]
        ax.bar(np.arange(len(names)) + (k - (len(models) - 1) / 2) * width, rmse, width,
               label=f"{label} (RMSE {result.rmse:.3g} N)")
    ax.axhline(noise, color="k", ls="--", lw=1, label=f"noise {noise:.3g} N")
    ax.set_xticks(range(len(names)), names, fontsize=8, rotation=15)
    ax.set_ylabel("RMSE [N]")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="y")


def before_after_figure(diagnosis) -> Figure:
    """RMSE of every curve for the baseline and after each addition, against the noise."""
    models = [("baseline", diagnosis.baseline)] + [
        ("+ " + s.added, s.fit) for s in diagnosis.steps]
    names = [curve.name for curve in diagnosis.baseline.problem.data]
    figure = Figure(figsize=(max(6.0, 1.1 * len(names) + 2), 4.2), layout="constrained")
    draw_rmse_per_curve(figure.add_subplot(), models, diagnosis.noise,
                        "error per curve, before and after each addition")
    return figure
