"""``jaxtube modes`` (registered by :mod:`fitting._cli.main`).

``jaxtube modes SPEC.toml --out DIR [--count N]``: the natural modes of a spec's structure
about its static equilibrium under gravity and its ``[[load]]`` forces (the path is not
followed); ``jaxtube modes --kite-fem initial.npz --out DIR [--pressure-bar P]
[--bending-scale S]``: about a kite_fem model hung from its suspension nodes. Writes
``modes.csv``, ``mode_shapes.png`` and ``summary.json``. Exit codes: 0 success; 1 the
equilibrium did not converge (nothing but ``summary.json`` is trustworthy: the files are
still written, marked); 2 bad input (nothing written).

``modes.csv`` columns, one row per mode, lowest first: ``mode`` (from 1), ``frequency_Hz``,
``angular_frequency_rad_per_s``, ``eigenvalue_rad2_per_s2`` (``omega^2``; negative:
unstable), ``kind`` (``elastic``, ``zero-frequency``: a rigid-body or mechanism mode,
``unstable``), ``max_node_motion_mm_per_sqrt_kg`` (largest node displacement of the
mass-normalised shape).
"""

from __future__ import annotations

import csv
import json
import sys
import time
from pathlib import Path

import jax
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import jaxtube as jt  # noqa: E402

from .common import (  # noqa: E402
    add_structure_source_arguments,
    bad_output_directory,
    positive_int,
    write_directory,
)

MODE_COLUMNS = ("mode", "frequency_Hz", "angular_frequency_rad_per_s", "eigenvalue_rad2_per_s2",
                "kind", "max_node_motion_mm_per_sqrt_kg")


def add_modes(subparsers) -> None:
    parser = subparsers.add_parser(
        "modes", help="natural modes of a spec's structure (or a kite_fem model) at rest",
        description="Natural frequencies and mode shapes about the static equilibrium: "
                    "modes.csv, mode_shapes.png, summary.json in --out.")
    add_structure_source_arguments(
        parser, "instead of a spec: a kite_fem model (initial.npz), hung from its suspension "
                "nodes")
    parser.add_argument("--count", type=positive_int, default=10,
                        help="modes to report (default 10)")
    parser.add_argument("--out", type=Path, required=True, help="output directory")
    parser.add_argument("--quiet", action="store_true", help="print only problems")
    parser.set_defaults(run=_run_modes)


def _equilibrium_from_spec(path: Path):
    structure, params, _, meta = jt.load_spec(path)
    return structure, params, jt.equilibrium(structure, params), meta.name or path.stem


def _equilibrium_from_kite_fem(path: Path, pressure_bar, bending_scale):
    model = jt.read_kite_fem(path)
    imported = jt.import_kite_fem(model, pressure_bar=pressure_bar, bending_scale=bending_scale)
    structure, params = imported.structure, imported.params
    solution, _ = jt.hang_until_converged(structure, params, steps=1)
    last = jax.tree_util.tree_map(lambda leaf: leaf[-1], solution)
    return structure, params, last, path.name


def mode_rows(modes: jt.Modes) -> list[dict]:
    """One ``modes.csv`` row per mode (:data:`MODE_COLUMNS`)."""
    rows = []
    motion = np.max(np.linalg.norm(np.asarray(modes.node_displacement), axis=-1), axis=-1)
    for k, (f, w, e, zero, unstable) in enumerate(zip(
            np.asarray(modes.frequency), np.asarray(modes.angular_frequency),
            np.asarray(modes.eigenvalue), np.asarray(modes.zero_frequency),
            np.asarray(modes.unstable))):
        kind = "zero-frequency" if zero else "unstable" if unstable else "elastic"
        rows.append({"mode": k + 1, "frequency_Hz": f"{f:.6g}",
                     "angular_frequency_rad_per_s": f"{w:.6g}",
                     "eigenvalue_rad2_per_s2": f"{e:.6g}", "kind": kind,
                     "max_node_motion_mm_per_sqrt_kg": f"{1e3 * motion[k]:.6g}"})
    return rows


def mode_shapes_figure(structure, positions: np.ndarray, modes: jt.Modes, title: str,
                       shown: int = 6):
    """The first ``shown`` mode shapes (3-D, equal axes): each tube's nodes at rest (grey)
    and displaced along the mode, scaled to a tenth of the structure's size."""
    count = min(shown, int(modes.frequency.shape[0]))
    columns = min(3, count)
    rows = -(-count // columns)
    figure = plt.figure(figsize=(4.2 * columns, 3.8 * rows))
    size = float(np.ptp(positions, axis=0).max()) or 1.0
    for k in range(count):
        ax = figure.add_subplot(rows, columns, k + 1, projection="3d")
        motion = np.asarray(modes.node_displacement[k])
        largest = float(np.linalg.norm(motion, axis=-1).max())
        moved = positions + (0.1 * size / largest if largest > 0 else 0.0) * motion
        for ids in structure.tube_node_ids or ((),):
            ids = np.asarray(ids, dtype=int)
            if ids.size:
                ax.plot(*positions[ids].T, color="0.7", lw=1)
                ax.plot(*moved[ids].T, color="C0", lw=1.5)
        if not structure.tube_node_ids:
            ax.plot(*positions.T, "o", color="0.7")
            ax.plot(*moved.T, "o-", color="C0")
        ax.set_title(f"mode {k + 1}: {float(modes.frequency[k]):.4g} Hz", fontsize=9)
        ax.set_box_aspect(np.maximum(np.ptp(moved, axis=0), 1e-3 * size))
        ax.tick_params(labelsize=6)
    figure.suptitle(title)
    figure.tight_layout()
    return figure


def _run_modes(args) -> int:
    started = time.perf_counter()
    out = Path(args.out)
    if bad_output_directory(out):
        return 2
    if (args.spec is None) == (args.kite_fem is None):
        print("error: give either a spec file or --kite-fem NPZ", file=sys.stderr)
        return 2
    try:
        if args.spec is not None:
            structure, params, solution, name = _equilibrium_from_spec(args.spec)
        else:
            structure, params, solution, name = _equilibrium_from_kite_fem(
                args.kite_fem, args.pressure_bar, args.bending_scale)
    except jt.SpecError as error:
        print(f"error: invalid spec\n{error}", file=sys.stderr)
        return 2
    except (jt.KiteFemFormatError, FileNotFoundError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    converged = bool(np.all(np.asarray(solution.converged)))
    if not converged:
        print("error: the static equilibrium did not converge; the modes below are about "
              "an unconverged state", file=sys.stderr)
    solved = time.perf_counter()
    count = min(args.count, int(jax.flatten_util.ravel_pytree(solution.state)[0].shape[0]))
    modes = jax.block_until_ready(jt.modes(structure, params, solution, count=count))
    analysed = time.perf_counter()
    rows = mode_rows(modes)
    positions = np.asarray(solution.node_position)
    figure = mode_shapes_figure(structure, positions, modes, f"{name}: natural modes")
    summary = {"source": str(args.spec or args.kite_fem), "equilibrium_converged": converged,
               "modes": len(rows), "frequency_Hz": [float(r["frequency_Hz"]) for r in rows],
               "equilibrium_seconds": round(solved - started, 3),
               "modes_seconds": round(analysed - solved, 3)}

    def write_csv(path):
        with open(path, "w", newline="") as file:
            writer = csv.DictWriter(file, fieldnames=MODE_COLUMNS)
            writer.writeheader()
            writer.writerows(rows)

    def write_summary(path):
        with open(path, "w") as file:
            json.dump(summary, file, indent=2, allow_nan=False)
            file.write("\n")

    write_directory(out, {"modes.csv": write_csv,
                          "mode_shapes.png": lambda path: figure.savefig(path, dpi=120),
                          "summary.json": write_summary})
    plt.close(figure)
    if not args.quiet:
        listed = ", ".join(f"{r['frequency_Hz']}" for r in rows[:5])
        print(f"{len(rows)} modes of {name} (first: {listed} Hz) in "
              f"{summary['modes_seconds']} s; wrote modes.csv, mode_shapes.png, summary.json "
              f"to {out}")
    return 0 if converged else 1
