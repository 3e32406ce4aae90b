"""``jaxtube simulate --kite-fem initial.npz --out DIR``: hang an imported kite_fem model and
write its results (registered by :mod:`fitting._cli.simulate`).

Outputs (written atomically: nothing half-written on failure):

- ``positions.csv``: ``node,x_m,y_m,z_m``, every node of the model in kite_fem numbering and
  frame (held nodes, which belong to no element, where they are);
- ``lines.csv``: one row per spring and per pulley rope: ``element`` (``canopy``,
  ``bridle`` or ``pulley``), ``row`` (row of ``spring_matrix`` / ``pulley_matrix``),
  ``nodes`` (kite_fem nodes, ``a-b`` or ``a-pulley-b``), ``rest_length_m``, ``length_m``,
  ``tension_N``, ``state`` (``taut`` or ``slack``);
- ``summary.json``: convergence (per gravity step), timings, weight and suspension
  reactions, counts of taut and slack lines;
- ``kite_shape.png``: the hung kite in 3-D (tubes, lines taut and slack apart, pulleys,
  canopy, masses).

Exit code 0 when every step converged, 1 otherwise (outputs still written, the failure
named), 2 for a bad model file.
"""

from __future__ import annotations

import csv
import json
import sys
import time
from pathlib import Path

import jax
import numpy as np

import jaxtube as jt

from .common import write_directory


def _write_lines(path, rows) -> None:
    with open(path, "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=list(rows[0]) if rows else ["element"])
        writer.writeheader()
        for row in rows:
            writer.writerow({k: repr(v) if isinstance(v, float) else v for k, v in row.items()})




def simulate_kite_fem(model_path, out, *, pressure_bar=None, bending_scale=None, steps=1,
                      centre_load_kg=0.0, tip_load_kg=0.0, restarts=8, quiet=False) -> int:
    """Hang the kite_fem model at ``model_path`` and write the outputs into ``out``
    (module docstring); returns the exit code. ``restarts``: further runs of Newton steps
    from where the last one stopped while it has not converged
    (:func:`jaxtube.hang_until_converged`)."""
    def say(message):
        if not quiet:
            print(message, file=sys.stderr, flush=True)

    started = time.perf_counter()
    try:
        model = jt.read_kite_fem(model_path)
        imported = jt.import_kite_fem(model, pressure_bar=pressure_bar, bending_scale=bending_scale,
                                   centre_load_kg=centre_load_kg, tip_load_kg=tip_load_kg)
    except (jt.KiteFemFormatError, FileNotFoundError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    structure, params = imported.structure, imported.params
    say(f"imported {model_path}: {model.node_count} nodes, {len(imported.tube_names)} tubes "
        f"({structure.segment_count} segments), {len(model.spring_kind)} lines, "
        f"{model.pulley_nodes.shape[0]} pulleys, {model.total_mass:.4g} kg; suspension "
        f"{', '.join(map(str, imported.suspension))}")
    hang = jax.jit(jt.hang_program(structure, steps))
    loaded = time.perf_counter()
    compiled = hang.lower(params, jt.undeformed_start(structure, params)).compile()
    compiled_at = time.perf_counter()
    say(f"compiled in {compiled_at - loaded:.1f} s; hanging in {steps} gravity step(s) ...")
    solution, runs = jt.hang_until_converged(structure, params, steps=steps, restarts=restarts,
                                          compiled=compiled)
    solution = jax.block_until_ready(solution)
    solved_at = time.perf_counter()
    converged = np.atleast_1d(np.asarray(solution.converged))
    failure = None
    try:
        jt.check_converged(solution, "hang")
    except RuntimeError as error:
        failure = str(error)
        print(failure, file=sys.stderr)
    positions = imported.kite_positions(np.asarray(solution.node_position)[-1])
    rows = jt.kite_fem_line_table(imported, solution)
    balance = jt.weight_and_reactions(imported, solution)
    taut = {group: sum(1 for r in rows if r["element"] == group and r["state"] == "taut")
            for group in ("canopy", "bridle", "pulley")}
    slack = {group: sum(1 for r in rows if r["element"] == group and r["state"] == "slack")
             for group in ("canopy", "bridle", "pulley")}
    summary = {
        "model": str(model_path),
        "converged": bool(converged.all()),
        "newton_runs": runs,
        "steps": [{"step": k + 1, "converged": bool(c),
                   "iterations": int(np.atleast_1d(np.asarray(solution.iterations))[k]),
                   "residual": float(np.atleast_1d(np.asarray(solution.residual))[k])}
                  for k, c in enumerate(converged)],
        "pressure_bar": None if pressure_bar is None else float(pressure_bar),
        "bending_scale": None if bending_scale is None else float(bending_scale),
        "total_mass_kg": balance["total_mass_kg"],
        "weight_and_loads_N": balance["weight_and_loads_N"].tolist(),
        "suspension_reactions_N": {str(n): r.tolist() for n, r in
                                   zip(imported.suspension, balance["reaction_N"])},
        "applied_moment_Nm": balance["applied_moment_Nm"].tolist(),
        "reaction_moment_Nm": balance["reaction_moment_Nm"].tolist(),
        "taut": taut,
        "slack": slack,
        "compile_seconds": round(compiled_at - loaded, 3),
        "seconds": round(solved_at - compiled_at, 3),
    }
    figure = jt.deformed_shape_figure(
        structure, jt.kite_fem_reference_positions(imported),
        np.asarray(solution.node_position), converged,
        line_taut=np.asarray(solution.line_taut), pulley_taut=np.asarray(solution.pulley_taut),
        point_mass=np.asarray(params.elements.point_mass), gravity=np.asarray(params.gravity),
        intermediate=0, title=f"{Path(model_path).name}: hung from "
        f"{' and '.join(map(str, imported.suspension))}")

    def write_summary(path):
        summary["total_seconds"] = round(time.perf_counter() - started, 3)
        with open(path, "w") as file:
            json.dump(summary, file, indent=2, allow_nan=False)
            file.write("\n")

    write_directory(Path(out), {
        "positions.csv": lambda path: jt.write_positions_csv(path, positions),
        "lines.csv": lambda path: _write_lines(path, rows),
        "kite_shape.png": lambda path: figure.savefig(path, dpi=130),
        "summary.json": write_summary,
    })
    say(f"{'converged' if failure is None else 'NOT converged'}: compile "
        f"{summary['compile_seconds']} s, solve {summary['seconds']} s; taut {taut}, slack "
        f"{slack}; reactions sum {np.round(balance['reaction_sum_N'], 3).tolist()} N against "
        f"weight {np.round(balance['weight_and_loads_N'], 3).tolist()} N; wrote positions.csv, "
        f"lines.csv, kite_shape.png, summary.json to {out}")
    return 0 if failure is None else 1


