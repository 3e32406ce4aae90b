"""``jaxtube simulate --kite-fem initial.npz --out DIR``: hang an imported kite_fem model and
write its results.

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

from .._model import check_converged
from .kite_fem import (
    hang_program,
    hang_until_converged,
    import_kite_fem,
    undeformed_start,
    write_positions_csv,
)
from .kite_fem_reader import KiteFemFormatError, read_kite_fem


def line_table(imported, solution, step: int = -1) -> list[dict]:
    """Rows of ``lines.csv`` (module docstring) at one step of a hang."""
    model = imported.model
    rows = []
    length = np.asarray(solution.line_length)[step]
    tension = np.asarray(solution.line_tension)[step]
    taut = np.asarray(solution.line_taut)[step]
    for k, (a, b) in enumerate(model.spring_nodes):
        rows.append(dict(element=imported.spring_group[k], row=k, nodes=f"{a}-{b}",
                         rest_length_m=float(model.spring_rest_length[k]),
                         length_m=float(length[k]), tension_N=float(tension[k]),
                         state="taut" if taut[k] else "slack"))
    rope = np.asarray(solution.pulley_length)[step]
    rope_tension = np.asarray(solution.pulley_tension)[step]
    rope_taut = np.asarray(solution.pulley_taut)[step]
    for k, (a, p, b) in enumerate(model.pulley_nodes):
        rows.append(dict(element="pulley", row=k, nodes=f"{a}-{p}-{b}",
                         rest_length_m=float(model.pulley_rest_length[k]),
                         length_m=float(rope[k]), tension_N=float(rope_tension[k]),
                         state="taut" if rope_taut[k] else "slack"))
    return rows


def _write_lines(path, rows) -> None:
    with open(path, "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=list(rows[0]) if rows else ["element"])
        writer.writeheader()
        for row in rows:
            writer.writerow({k: repr(v) if isinstance(v, float) else v for k, v in row.items()})


def weight_and_reactions(imported, solution, step: int = -1) -> dict:
    """Total weight and applied loads [N] (at the step's ``load_factor``), the fixed points'
    reactions [N] and the moment balance about the origin [N m] at one step of
    :func:`hang_kite` (all in kite_fem's frame)."""
    params = imported.params
    structure = imported.structure
    from .._plot_elements import point_row_nodes

    rows = point_row_nodes(structure.elements, structure.node_count)
    position = np.asarray(solution.node_position)[step]
    mass_nodes = rows[np.asarray(structure.elements.mass_points, dtype=int)]
    factor = float(np.atleast_1d(np.asarray(solution.load_factor))[step])
    mass = np.asarray(params.elements.point_mass, dtype=float)
    gravity = factor * np.asarray(params.gravity, dtype=float)
    weight = mass[:, None] * gravity[None, :]
    loads = [(mass_nodes, weight)]
    tube_force = factor * np.asarray(params.node_force, dtype=float)
    loads.append((np.arange(tube_force.shape[0]), tube_force))
    own = factor * np.asarray(params.elements.point_force, dtype=float)
    loads.append((structure.node_count + np.arange(own.shape[0]), own))
    applied = sum(f.sum(axis=0) for _, f in loads)
    moment = sum(np.cross(position[n], f).sum(axis=0) for n, f in loads)
    fixed = structure.node_count + np.asarray(structure.elements.fixed_points, dtype=int)
    reaction = np.asarray(solution.fixed_point_reaction)[step].reshape(-1, 3)
    reaction_moment = np.cross(position[fixed], reaction).sum(axis=0)
    return dict(weight_and_loads_N=applied, reaction_N=reaction,
                reaction_sum_N=reaction.sum(axis=0), applied_moment_Nm=moment,
                reaction_moment_Nm=reaction_moment, total_mass_kg=float(mass.sum()))


def simulate_kite_fem(model_path, out, *, pressure_bar=None, bending_scale=None, steps=1,
                      centre_load_kg=0.0, tip_load_kg=0.0, restarts=8, quiet=False) -> int:
    """Hang the kite_fem model at ``model_path`` and write the outputs into ``out``
    (module docstring); returns the exit code. ``restarts``: further runs of Newton steps
    from where the last one stopped while it has not converged
    (:func:`~jaxtube._io.kite_fem.hang_until_converged`)."""
    from .._cli import write_directory  # the CLI's atomic writer
    from .._plot import deformed_shape_figure

    def say(message):
        if not quiet:
            print(message, file=sys.stderr, flush=True)

    started = time.perf_counter()
    try:
        model = read_kite_fem(model_path)
        imported = import_kite_fem(model, pressure_bar=pressure_bar, bending_scale=bending_scale,
                                   centre_load_kg=centre_load_kg, tip_load_kg=tip_load_kg)
    except (KiteFemFormatError, FileNotFoundError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    structure, params = imported.structure, imported.params
    say(f"imported {model_path}: {model.node_count} nodes, {len(imported.tube_names)} tubes "
        f"({structure.segment_count} segments), {len(model.spring_kind)} lines, "
        f"{model.pulley_nodes.shape[0]} pulleys, {model.total_mass:.4g} kg; suspension "
        f"{', '.join(map(str, imported.suspension))}")
    hang = jax.jit(hang_program(structure, steps))
    loaded = time.perf_counter()
    compiled = hang.lower(params, undeformed_start(structure, params)).compile()
    compiled_at = time.perf_counter()
    say(f"compiled in {compiled_at - loaded:.1f} s; hanging in {steps} gravity step(s) ...")
    solution, runs = hang_until_converged(structure, params, steps=steps, restarts=restarts,
                                          compiled=compiled)
    solution = jax.block_until_ready(solution)
    solved_at = time.perf_counter()
    converged = np.atleast_1d(np.asarray(solution.converged))
    failure = None
    try:
        check_converged(solution, "hang")
    except RuntimeError as error:
        failure = str(error)
        print(failure, file=sys.stderr)
    positions = imported.kite_positions(np.asarray(solution.node_position)[-1])
    rows = line_table(imported, solution)
    balance = weight_and_reactions(imported, solution)
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
    figure = deformed_shape_figure(
        structure, reference_positions(imported),
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
        "positions.csv": lambda path: write_positions_csv(path, positions),
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


def reference_positions(imported) -> np.ndarray:
    """Reference positions of every jaxtube node (tube nodes, then point nodes) [m]."""
    params = imported.params
    return np.concatenate([np.asarray(params.node_position),
                           np.asarray(params.elements.point_position)])
