"""Shared parts of the figure scripts: command line, "measured-style" bench curves from the
independent continuum solver, and the fit.

The original measurements of Breukels & Ockels (2008) are not public. The bench-style
curves here come from :class:`fitting.continuum.CantileverModel` (a planar continuum
elastica integrated by scipy's shooting method; it does not import jaxtube's solver) given a
known moment-curvature law, with Gaussian noise; they are then fitted with jaxtube's
rigid-segment model (:func:`fitting.fit`). Quick mode (``--quick``, for CI) uses two curves
of six points, a 6-segment model and a few Levenberg-Marquardt iterations: it checks that
the script runs and writes its figure, not the quality of the fit.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import jax
import numpy as np

import fitting
import jaxtube as jt
from experiments.make_calibration_data import write_noisy_curves
from fitting import continuum

HERE = Path(__file__).resolve().parent
QUICK_POINTS = 6


def parser(name: str, description: str) -> argparse.ArgumentParser:
    """``--quick`` and ``--out`` (default ``experiments/figures/NAME.png``)."""
    args = argparse.ArgumentParser(description=description)
    args.add_argument("--quick", action="store_true", help="a tiny run (CI)")
    args.add_argument("--out", type=Path, default=HERE / "figures" / f"{name}.png",
                      help="the PNG to write")
    return args


def continuum_curve(law: jt.AbstractMomentLaw, pressure: float, radius: float,
                    length: float, points: int, fraction: float = 0.85):
    """Tip deflections [m] of the continuum cantilever at ``points`` dead tip loads [N]
    evenly spaced up to ``fraction`` of the law's collapse moment over L."""
    compiled = jax.jit(lambda kappa: law.moment(kappa, pressure, radius))
    _, kappa_c = fitting.regime_boundaries(law, pressure, radius)
    collapse_moment = float(law.moment(kappa_c, pressure, radius))
    model = continuum.CantileverModel(length, continuum.law_from_moment(
        lambda kappa: float(compiled(kappa)), curvature_scale=float(kappa_c) / 10))
    loads = fraction * collapse_moment / length * np.arange(1, points + 1) / points
    return np.array([model.tip_deflection(load) for load in loads]), loads


def measured(curves, noise_fraction: float = 0.015, seed: int = 7) -> fitting.MeasuredData:
    """Noisy measurement data from ``(name, p_bar, r, L, deflections, loads)`` curves: noise
    of ``noise_fraction`` of the largest force and 0.05 mm, written as a measurement CSV and
    read back with :func:`fitting.load_measurements` (the route of real data)."""
    rng = np.random.default_rng(seed)
    noise = noise_fraction * max(float(c[5][-1]) for c in curves)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "bench.csv"
        write_noisy_curves(path, curves, noise, rng)
        return fitting.load_measurements(path)


def fit(data: fitting.MeasuredData, quick: bool, form: str = "paper") -> fitting.FitResult:
    """The default calibration (pivots 1,1,1; ``form`` "paper" ``A (p r^3)^B`` or
    "separate" ``A p^B r^C``); small in quick mode."""
    rig = fitting.CantileverRig(segments=6 if quick else fitting.DEFAULT_SEGMENTS)
    options = fitting.FitOptions(max_iterations=4 if quick else 60, progress=not quick)
    return fitting.fit(data, fitting.PivotScaling(form=form), rig, options)


def determined(result: fitting.FitResult, coordinate: str, pivot: int) -> bool:
    """Whether the fit determines the (cumulative) pivot ``pivot`` (1-based) of
    ``coordinate`` ("kappa" or "M"): every fitted parameter of it and of the pivots before
    it, whose increments it sums, is identified (``FitResult.parameters``)."""
    prefixes = tuple(f"{coordinate}[{k}]." for k in range(1, pivot + 1))
    rows = [p for p in result.parameters if p.name.startswith(prefixes) and not p.fixed]
    return all(p.identified for p in rows)


def save(figure, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=120)
    print(f"wrote {path}")
