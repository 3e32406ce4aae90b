"""``jaxtube sweep``: a bending law over a pressure x radius (x length) grid of cantilevers.

``jaxtube sweep (--params parameters.json | --law NAME ...) --pressure-bar 0.1:0.5:41
--radius-m 0.03:0.15:41 --length-m 1 --tip-load-N 20 --out DIR``

With ``--scheduler ADDRESS`` the grid is cut into one block per worker of that Dask cluster
(:func:`fitting.sweep_on_cluster`; the ``study`` extra), for grids too large for one machine.

Ranges are ``START:STOP:N`` (N evenly spaced values, both ends included) or one value.
Laws: ``--params`` (a fitted spline law, :func:`fitting.load_law`), or ``--law
tension_field --wall-modulus-N-per-m E_t``, ``--law empirical_2011`` (Breukels 2011),
``--law linear --bending-stiffness-N-m2 EI``. The quantities are defined in
:mod:`fitting._sweep.sweep`.

Outputs in DIR (written atomically; nothing is written on bad input):

- ``sweep.csv``: one row per grid point: ``pressure_bar, radius_m, length_m, tip_load_N,
  pr3_Nm`` (``p r^3`` [N m]), ``initial_stiffness_Nm2, wrinkling_moment_Nm,
  collapse_moment_Nm, wrinkling_load_N, collapse_load_N, tip_deflection_mm,
  converged`` (1 or 0), ``newton_iterations, wrinkling_moment_mismatch,
  collapse_moment_mismatch, status`` ("ok" or the reasons in words). Values that could
  not be computed are left blank.
- ``initial_stiffness.png, wrinkling_load.png, collapse_load.png, tip_deflection.png``:
  heatmaps over (pressure, radius), one panel per length (at most four, evenly chosen),
  with labelled contours of ``p r^3`` and failed points crossed out.
- ``summary.json``: grid, law, settings, devices, point count, failed count, counts per
  reason, value ranges, wall time.

Exit codes: 0 success; 1 some points failed (outputs written, points marked); 2 bad
arguments (nothing written).
"""

from __future__ import annotations

import argparse
import collections
import csv
import math
import sys
import time
from pathlib import Path

import numpy as np

import jaxtube as jt

from .._calibrate.parameters_file import load_law, without_effects_words
from .._cluster import open_client
from .._data.units import BAR_PER_PA, MM_PER_M
from .._json import write_json
from .._sweep.cluster import sweep_on_cluster
from .._sweep.sweep import SweepSettings, sweep
from .common import bad_output_directory, positive_float, positive_int, write_directory

LAWS = ("tension_field", "empirical_2011", "linear")
QUANTITIES = (  # (result field, file, title, unit, factor from SI)
    ("initial_stiffness", "initial_stiffness.png", "initial bending stiffness EI0", "N m^2",
     1.0),
    ("wrinkling_load", "wrinkling_load.png", "wrinkling load (root at M_w)", "N", 1.0),
    ("collapse_load", "collapse_load.png", "collapse load (root at M_c)", "N", 1.0),
    ("tip_deflection", "tip_deflection.png", "tip deflection at the given load", "mm", MM_PER_M),
)
MAX_PANELS = 4


def grid_range(text: str) -> np.ndarray:
    """argparse type: ``START:STOP:N`` (positive numbers, START <= STOP, integer N >= 1;
    N = 1 needs START = STOP) or one positive number."""
    parts = text.split(":")
    expected = f"expected START:STOP:N (e.g. 0.1:0.5:41) or one positive number, found {text!r}"
    try:
        if len(parts) == 1:
            values = np.array([float(parts[0])])
        elif len(parts) == 3:
            start, stop, count = float(parts[0]), float(parts[1]), int(parts[2])
            if count < 1 or stop < start or (count == 1 and stop != start):
                raise ValueError
            values = np.linspace(start, stop, count)
        else:
            raise ValueError
    except ValueError:
        raise argparse.ArgumentTypeError(expected) from None
    if not (np.all(np.isfinite(values)) and np.all(values > 0)):
        raise argparse.ArgumentTypeError(f"expected positive values, found {text!r}")
    return values


def add_sweep(subparsers) -> None:
    parser = subparsers.add_parser(
        "sweep", help="a bending law over a pressure x radius grid of cantilevers",
        description="Evaluate a fitted or given bending law on the standard bench cantilever "
                    "over a grid: initial bending stiffness, wrinkling and collapse loads, "
                    "tip deflection at a given load. Writes sweep.csv, heatmaps and "
                    "summary.json. The grid is split over every JAX device of the process; "
                    "on a CPU, JAXTUBE_CPU_DEVICES=auto (set before the command) gives one "
                    "device per core.")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--params", type=Path, help="parameters.json of 'jaxtube fit'")
    source.add_argument("--law", choices=LAWS, help="a given law instead of a fitted one")
    parser.add_argument("--wall-modulus-N-per-m", type=positive_float, default=None,
                        help="E t of --law tension_field [N/m]")
    parser.add_argument("--bending-stiffness-N-m2", type=positive_float, default=None,
                        help="EI of --law linear [N m^2]")
    parser.add_argument("--pressure-bar", type=grid_range, required=True,
                        metavar="START:STOP:N", help="overpressures [bar]")
    radius = parser.add_mutually_exclusive_group(required=True)
    radius.add_argument("--radius-m", type=grid_range, metavar="START:STOP:N",
                        help="tube radii [m]")
    radius.add_argument("--radius-mm", type=grid_range, metavar="START:STOP:N",
                        help="tube radii [mm]")
    parser.add_argument("--length-m", type=grid_range, default=np.array([1.0]),
                        metavar="L|START:STOP:N", help="cantilever lengths [m] (default 1)")
    parser.add_argument("--tip-load-N", type=float, required=True,
                        help="dead tip load of the tip deflection [N] (>= 0)")
    parser.add_argument("--segments", type=positive_int, default=None,
                        help="rigid segments of the cantilever (default 12)")
    parser.add_argument("--chunk-size", type=positive_int, default=None,
                        help="points per compiled call (default 512; bounds the memory)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="sweep on the Dask cluster of this scheduler (e.g. "
                             "tcp://host:8786; needs the study extra): the grid is cut into "
                             "one block per worker")
    parser.add_argument("--out", type=Path, required=True, help="output directory")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(run=run_sweep)


def _law(args):
    """The bending law and a description of it, or raise ValueError naming the flag."""
    if args.params is not None:
        law = load_law(args.params)
        return law, (f"fitted spline law from {args.params}"
                     + without_effects_words(args.params))
    if args.law != "tension_field" and args.wall_modulus_N_per_m is not None:
        raise ValueError("--wall-modulus-N-per-m is only used with --law tension_field")
    if args.law != "linear" and args.bending_stiffness_N_m2 is not None:
        raise ValueError("--bending-stiffness-N-m2 is only used with --law linear")
    if args.law == "tension_field":
        if args.wall_modulus_N_per_m is None:
            raise ValueError("--law tension_field needs --wall-modulus-N-per-m (E t [N/m], "
                             "e.g. 150e3)")
        return (jt.TensionFieldLaw(args.wall_modulus_N_per_m),
                f"tension-field law, E t = {args.wall_modulus_N_per_m:g} N/m")
    if args.law == "linear":
        if args.bending_stiffness_N_m2 is None:
            raise ValueError("--law linear needs --bending-stiffness-N-m2 (EI [N m^2])")
        return (jt.LinearLaw(args.bending_stiffness_N_m2),
                f"linear law, EI = {args.bending_stiffness_N_m2:g} N m^2")
    return jt.EmpiricalBendingLaw2011(), "empirical law of Breukels (2011)"


def run_sweep(args) -> int:
    started = time.perf_counter()
    out = Path(args.out)
    if bad_output_directory(out):
        return 2
    if not (math.isfinite(args.tip_load_N) and args.tip_load_N >= 0):
        print(f"error: --tip-load-N must be a finite number >= 0, found {args.tip_load_N:g}",
              file=sys.stderr)
        return 2
    try:
        law, law_text = _law(args)
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    radius = (args.radius_m if args.radius_m is not None
              else args.radius_mm * jt.unit_factor("length", "mm"))
    pressure = args.pressure_bar * jt.unit_factor("pressure", "bar")
    settings = SweepSettings()
    overrides = {"segments": args.segments, "chunk_size": args.chunk_size}
    settings = SweepSettings(**{**{k: getattr(settings, k) for k in
                                   ("segments", "chunk_size")},
                                **{k: v for k, v in overrides.items() if v is not None}})
    grid = np.meshgrid(pressure, radius, args.length_m, indexing="ij")
    print(f"sweep of {grid[0].size} points ({pressure.size} pressures x {radius.size} radii x "
          f"{args.length_m.size} lengths), {law_text}; compiling (the first chunk takes a "
          "while) ...", file=sys.stderr, flush=True)
    if args.scheduler is None:
        result = sweep(law, *grid, args.tip_load_N, settings, progress=not args.quiet)
    else:
        try:
            client = open_client(args.scheduler)
        except (OSError, ValueError) as error:
            print(f"error: --scheduler {args.scheduler}: {error}", file=sys.stderr)
            return 2
        with client:
            result = sweep_on_cluster(client, law, *grid, args.tip_load_N, settings,
                                      progress=not args.quiet)
    reasons = result.failure_reasons()
    summary = _summary(args, result, reasons, law_text, time.perf_counter() - started)
    figures = {name: heatmap(result, field, title, unit, factor)
               for field, name, title, unit, factor in QUANTITIES}
    writers = {"sweep.csv": lambda path: write_csv(path, result, reasons)}
    for name, figure in figures.items():
        writers[name] = lambda path, figure=figure: figure.savefig(path, dpi=120)
    writers["summary.json"] = lambda path: write_json(path, summary)
    write_directory(out, writers)
    failed = summary["failed_points"]
    print(f"{summary['points']} points in {result.seconds:.1f} s "
          f"({summary['points'] / result.seconds:.1f} points/s on {result.devices} "
          f"device(s)); failed: {failed}; wrote sweep.csv, "
          f"{', '.join(figures)}, summary.json to {out}")
    for reason, count in summary["reasons"].items():
        if reason != "ok":
            print(f"{count} point(s): {reason}", file=sys.stderr)
    return 1 if failed else 0


def _summary(args, result, reasons, law_text: str, seconds: float) -> dict:
    ranges = {}
    for field, _, _, unit, factor in QUANTITIES:
        values = getattr(result, field) * factor
        finite = values[np.isfinite(values)]
        ranges[f"{field}_{unit.replace(' ', '').replace('^', '')}"] = (
            [float(finite.min()), float(finite.max())] if finite.size else None)
    return {
        "law": law_text,
        "pressure_bar": [float(v) for v in args.pressure_bar],
        "radius_m": [float(v) for v in np.unique(result.radius)],
        "length_m": [float(v) for v in args.length_m],
        "tip_load_N": float(args.tip_load_N),
        "segments": result.settings.segments,
        "chunk_size": result.settings.chunk_size,
        "devices": result.devices,
        "points": int(result.pressure.size),
        "failed_points": result.failed_count,
        "reasons": dict(collections.Counter(reasons.reshape(-1).tolist())),
        "ranges": ranges,
        "sweep_s": round(result.seconds, 3),
        "wall_time_s": round(seconds, 3),
    }


def write_csv(path: Path, result, reasons) -> None:
    """``sweep.csv`` (columns in the module docstring); blank where a value is missing."""
    columns = [("pressure_bar", result.pressure * BAR_PER_PA), ("radius_m", result.radius),
               ("length_m", result.length), ("tip_load_N", result.tip_load),
               ("pr3_Nm", result.pressure * result.radius**3),
               ("initial_stiffness_Nm2", result.initial_stiffness),
               ("wrinkling_moment_Nm", result.wrinkling_moment),
               ("collapse_moment_Nm", result.collapse_moment),
               ("wrinkling_load_N", result.wrinkling_load),
               ("collapse_load_N", result.collapse_load),
               ("tip_deflection_mm", result.tip_deflection * MM_PER_M),
               ("converged", (~result.failed).astype(int)),
               ("newton_iterations", result.iterations),
               ("wrinkling_moment_mismatch", result.wrinkling_mismatch),
               ("collapse_moment_mismatch", result.collapse_mismatch),
               ("status", reasons)]
    flat = [(name, np.asarray(values).reshape(-1)) for name, values in columns]
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow([name for name, _ in flat])
        for i in range(flat[0][1].size):
            row = []
            for _, values in flat:
                value = values[i]
                if isinstance(value, (float, np.floating)):
                    row.append(f"{float(value):.10g}" if math.isfinite(value) else "")
                else:
                    row.append(str(value))
            writer.writerow(row)


def heatmap(result, field: str, title: str, unit: str, factor: float):
    """Figure of ``field`` over (pressure [bar], radius [mm]) per length, with ``p r^3``
    contours [N m] and failed points marked. Expects the ``[P, R, L]`` grid of the CLI."""
    # Lazy: pyplot (for its colour bars and contour labels) is imported only when a figure
    # is drawn, with the Agg backend chosen first so no window can open.
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    values = getattr(result, field) * factor
    pressure_bar = result.pressure[:, 0, 0] * BAR_PER_PA
    radius_mm = result.radius[0, :, 0] * MM_PER_M
    lengths = np.unique(np.linspace(0, values.shape[2] - 1,
                                    min(values.shape[2], MAX_PANELS)).round().astype(int))
    figure, axes = plt.subplots(1, lengths.size, figsize=(5.2 * lengths.size + 0.8, 4.4),
                                squeeze=False, constrained_layout=True)
    finite = values[np.isfinite(values) & (values > 0)]
    norm = (LogNorm(finite.min(), finite.max()) if finite.size and finite.max() > 3 * finite.min()
            else None)
    for ax, k in zip(axes[0], lengths):
        panel = values[:, :, k].T  # rows: radius, columns: pressure
        if pressure_bar.size > 1 and radius_mm.size > 1:
            mesh = ax.pcolormesh(pressure_bar, radius_mm, np.ma.masked_invalid(panel),
                                 shading="nearest", cmap="viridis", norm=norm)
            pr3 = (result.pressure[:, :, k] * result.radius[:, :, k] ** 3).T
            levels = np.geomspace(pr3.min(), pr3.max(), 7)[1:-1]
            contours = ax.contour(pressure_bar, radius_mm, pr3, levels=levels, colors="white",
                                  linewidths=0.8, linestyles="--")
            ax.clabel(contours, fmt=lambda v: f"{v:.3g}", fontsize=7)
        else:
            mesh = ax.scatter(np.repeat(pressure_bar, radius_mm.size),
                              np.tile(radius_mm, pressure_bar.size), c=panel.T.reshape(-1),
                              cmap="viridis", norm=norm, s=80)
        bad = result.failed[:, :, k].T
        if bad.any():
            rr, pp = np.nonzero(bad)
            ax.plot(pressure_bar[pp], radius_mm[rr], "x", color="red", ms=6,
                    label=f"failed ({bad.sum()})")
            ax.legend(loc="upper left", fontsize=8)
        ax.set_xlabel("pressure [bar]")
        ax.set_ylabel("radius [mm]")
        ax.set_title(f"L = {result.length[0, 0, k]:g} m", fontsize=10)
        figure.colorbar(mesh, ax=ax, label=f"{field.replace('_', ' ')} [{unit}]")
    shown = values.shape[2]
    note = "" if lengths.size == shown else f" ({lengths.size} of {shown} lengths)"
    figure.suptitle(f"{title}; dashed: p r^3 [N m]{note}; tip load "
                    f"{float(result.tip_load.flat[0]):g} N" if field == "tip_deflection" else
                    f"{title}; dashed: p r^3 [N m]{note}", fontsize=11)
    return figure
