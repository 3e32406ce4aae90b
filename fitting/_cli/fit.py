"""``jaxtube fit`` and ``jaxtube predict`` (registered by :mod:`fitting._cli.main`).

``jaxtube fit DATA.csv --out DIR``: fit the bending law's pivot scaling to every curve of
the measurement file (format in :mod:`fitting._data`), print the parameter table with
standard errors, identifiability notes and per-curve / overall RMSE, and write into DIR:

``--effect NAME`` (repeatable) fits an effect's parameters too: a built-in name or
``path/to/file.py:ClassName`` (a :class:`fitting.Effect` subclass).

- ``parameters.json``: the fitted law and its uncertainty (format in
  :mod:`fitting._calibrate.result`); ``jaxtube simulate --params`` and ``jaxtube predict``
  load it;
- ``fit.png``: fitted against measured curves with 95 % bands, and residuals;
- ``curves.csv``: ``curve,deflection_mm,force_N,model_force_N,residual_N,worst_regime``.

``jaxtube predict --params parameters.json --pressure-bar P --radius-m R --length-m L
--max-deflection-mm U --out DIR``: the fitted model's cantilever curve at any specimen, with
its 95 % band, as ``prediction.csv`` and ``prediction.png``.

Exit codes: 0 success; 1 the fit ran but did not converge (outputs written and marked);
2 bad input (nothing written).
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path

import numpy as np

import jaxtube as jt

from .._bench.effects import resolve_effect
from .._bench.rig import DEFAULT_SEGMENTS, CantileverRig
from .._bench.scaling import FORMS, PivotScaling
from .._calibrate.fit import fit
from .._calibrate.noise import estimate_noise_with_error
from .._calibrate.parameters_file import load_law, predict_from_document
from .._calibrate.problem import FitError, FitOptions, Prior
from .._calibrate.result import Z_95
from .._data.units import MM_PER_M
from .._diagnose.verdict import noise_words
from .._figures.plots import fit_figure, prediction_figure
from .._json import write_json
from .common import (
    add_data_argument,
    add_model_size_arguments,
    bad_output_directory,
    load_input,
    positive_float,
    positive_int,
    write_directory,
)


def _assignment(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    try:
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE like M[1].B=1.0, found {text!r}")


def _prior(text: str) -> tuple[str, Prior]:
    name, sep, value = text.partition("=")
    mean, _, sd = value.partition("+-")
    try:
        return name.strip(), Prior(float(mean), float(sd))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected NAME=MEAN+-SD like kappa[1].B=1.0+-0.2, found {text!r}")


def add_fit(subparsers) -> None:
    parser = subparsers.add_parser(
        "fit", help="fit the bending law's scaling factors A, B to measured curves",
        description="Fit the pivot scaling of the three-regime spline law to every measured "
                    "force-deflection curve at once (Levenberg-Marquardt through the "
                    "equilibrium solver), with standard errors and 95 % bands.")
    add_data_argument(parser)
    parser.add_argument("--out", type=Path, required=True, help="output directory")
    parser.add_argument("--form", choices=FORMS, default="paper",
                        help="pivot scaling: paper A (p r^3)^B, or separate A p^B r^C")
    add_model_size_arguments(parser)
    parser.add_argument("--noise-N", type=positive_float, default=None,
                        help="force noise standard deviation [N] (default: estimated)")
    parser.add_argument("--fix", type=_assignment, action="append", default=[],
                        metavar="NAME=VALUE", help="hold a parameter fixed (repeatable)")
    parser.add_argument("--prior", type=_prior, action="append", default=[],
                        metavar="NAME=MEAN+-SD", help="Gaussian prior (repeatable; on log A "
                                                      "for A, sd relative)")
    parser.add_argument("--effect", action="append", default=[], metavar="NAME|FILE.py:Class",
                        help="also fit an effect: shear, reinforcement, clamp_compliance, "
                             "self_weight, or a user's Effect subclass (repeatable)")
    parser.add_argument("--robust", action="store_true", help="Huber loss (outliers)")
    parser.add_argument("--multistart", type=positive_int, default=1,
                        help="number of starts (default 1: the physics-based guess)")
    parser.add_argument("--max-iterations", type=positive_int, default=60)
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(run=run_fit)


def add_predict(subparsers) -> None:
    parser = subparsers.add_parser(
        "predict", help="the fitted model's cantilever curve at any pressure, radius, length",
        description="Predict the tip force-deflection curve of a cantilever with a fitted "
                    "law (parameters.json of 'jaxtube fit'), with its 95 %% band.")
    parser.add_argument("--params", type=Path, required=True, help="parameters.json")
    parser.add_argument("--pressure-bar", type=positive_float, required=True)
    parser.add_argument("--radius-m", type=positive_float, required=True)
    parser.add_argument("--length-m", type=positive_float, required=True)
    parser.add_argument("--max-deflection-mm", type=positive_float, required=True)
    parser.add_argument("--points", type=positive_int, default=25)
    parser.add_argument("--out", type=Path, required=True, help="output directory")
    parser.set_defaults(run=run_predict)


def run_fit(args) -> int:
    started = time.perf_counter()
    data = load_input(args)
    if data is None:
        return 2
    try:
        scaling = PivotScaling(form=args.form, pivots_per_regime=args.pivots)
        options = FitOptions(noise_N=args.noise_N, fixed=dict(args.fix),
                             priors=dict(args.prior), loss="huber" if args.robust else "linear",
                             multistart=args.multistart, max_iterations=args.max_iterations,
                             progress=not args.quiet)
        rig = CantileverRig(segments=args.segments or DEFAULT_SEGMENTS)
        effects = tuple(resolve_effect(text) for text in args.effect)
        print(f"fitting {len(data)} curves ({data.point_count} points) from {args.data}; "
              f"{args.form} scaling, pivots {','.join(map(str, args.pivots))}; compiling the "
              "model (the first evaluation takes a while) ...", file=sys.stderr, flush=True)
        result = fit(data, scaling, rig, options, effects=effects)
    except (ValueError, FitError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    figure = fit_figure(result)
    document = result.to_json()
    document["wall_time_s"] = round(time.perf_counter() - started, 3)

    def write_curves(path):
        with open(path, "w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(["curve", "deflection_mm", "force_N", "model_force_N", "residual_N",
                             "worst_regime"])
            for curve, force, regime in zip(data, result.force, result.joint_regime):
                worst = regime.max(axis=-1)
                for u, f, m, w in zip(curve.deflection, curve.force, force, worst):
                    writer.writerow([curve.name, f"{u * MM_PER_M:.6g}", f"{f:.6g}", f"{m:.6g}",
                                     f"{m - f:.6g}", int(w)])

    write_directory(args.out, {"parameters.json": lambda path: write_json(path, document),
                               "curves.csv": write_curves,
                               "fit.png": lambda path: figure.savefig(path, dpi=120)})
    print(fit_report(result))
    print(f"wrote parameters.json, curves.csv, fit.png to {args.out}")
    return 0 if result.convergence.converged else 1


def fit_report(result) -> str:
    """Parameter table, identifiability notes, errors per curve and the optimiser's report."""
    lines = [result.table(), ""]
    for sentence in result.identifiability:
        lines.append("note: " + sentence)
    lines.append("")
    lines.append(f"{'curve':<16}{'RMSE [N]':>10}{'max |err| [N]':>15}{'bias [N]':>10}")
    for row in result.curve_errors():
        lines.append(f"{row['curve']:<16}{row['rmse_N']:>10.4g}{row['max_error_N']:>15.4g}"
                     f"{row['bias_N']:>10.4g}")
    lines.append(f"{'overall':<16}{result.rmse:>10.4g}")
    estimate = None if result.problem.noise_given else estimate_noise_with_error(
        result.problem.data)
    lines.append(noise_words(result.noise, estimate, result))
    c = result.convergence
    lines.append(f"optimiser: {'converged' if c.converged else 'NOT CONVERGED'} ({c.message}); "
                 f"{c.iterations} iterations, {c.evaluations} evaluations, {c.solver_calls} "
                 f"curve solves, {c.seconds:.1f} s")
    return "\n".join(lines)


def run_predict(args) -> int:
    if bad_output_directory(args.out):
        return 2
    try:
        load_law(args.params)  # validates the file with clear errors
        document = json.loads(Path(args.params).read_text())
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    deflection = np.linspace(args.max_deflection_mm / args.points, args.max_deflection_mm,
                             args.points) * jt.unit_factor("length", "mm")
    pressure = args.pressure_bar * jt.unit_factor("pressure", "bar")
    radius, length = args.radius_m, args.length_m
    try:
        force, sd = predict_from_document(document, pressure, radius, length, deflection)
    except (ValueError, KeyError) as error:
        print(f"error: {args.params}: {error}", file=sys.stderr)
        return 2
    except RuntimeError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    label = (f"{args.pressure_bar:g} bar, r = {args.radius_m * MM_PER_M:g} mm, "
             f"L = {args.length_m:g} m ({args.params})")
    figure = prediction_figure(deflection * MM_PER_M, force, sd, label)

    def write_csv(path):
        with open(path, "w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(["deflection_mm", "force_N", "force_low_N", "force_high_N"])
            for u, f, s in zip(deflection, force, sd):
                writer.writerow([f"{u * MM_PER_M:.6g}", f"{f:.6g}", f"{f - Z_95 * s:.6g}",
                                 f"{f + Z_95 * s:.6g}"])

    write_directory(args.out, {"prediction.csv": write_csv,
                               "prediction.png": lambda path: figure.savefig(path, dpi=120)})
    print(f"predicted {args.points} points up to {args.max_deflection_mm:g} mm: force "
          f"{force[-1]:.4g} N +- {Z_95 * sd[-1]:.3g} N (95 %) at the largest deflection; "
          f"wrote prediction.csv, prediction.png to {args.out}")
    return 0
