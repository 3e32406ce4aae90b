"""``jaxtube simulate`` (registered by :mod:`fitting._cli.main`).

``jaxtube simulate SPEC.toml --out DIR [--steps N] [--quiet]``: load a TOML spec (format
  in :mod:`jaxtube.load_spec`), compile and run the load path, and write ``path.csv``,
  ``force_deflection.png``, ``deformed_shape.png`` and ``summary.json`` into ``DIR``.
  ``jaxtube simulate --kite-fem initial.npz --out DIR [--pressure-bar P] [--bending-scale S]``
  hangs a kite_fem model instead (:mod:`fitting._cli.kite_fem`). A spec with a
  ``[dynamics]`` table is simulated in time instead of along its path, writing
  ``history.csv``, ``history.png``, ``response.gif``, ``modes.csv`` and ``summary.json``
  (:mod:`fitting._cli.dynamics`).
Exit codes: 0 success; 1 the run finished but some steps did not converge (the outputs
are written, with those steps marked); 2 a bad spec or bad arguments (nothing written).

Steps are numbered from 1 (step 1 is the first load increment; the undeformed state is
step 0 and is not listed).

``path.csv`` columns, one row per step:

- ``step``; ``load_factor`` (1 under displacement control);
- ``control_displacement_mm``: displacement of the path node along the path direction;
- ``control_force_N``: the actuator's force along the direction (displacement control) or
  the applied point force at the path node along it (force control);
- ``control_node_dx_mm``, ``control_node_dy_mm``, ``control_node_dz_mm``: the path node's
  displacement vector;
- ``max_moment_Nm`` (largest joint moment magnitude), ``max_bending_moment_Nm`` (bending
  part only);
- ``joints_wrinkled``, ``joints_collapsed`` (counts), ``worst_regime`` (0 unwrinkled,
  1 wrinkled, 2 collapsed);
- ``converged`` (1 or 0), ``iterations`` (Newton steps), ``residual`` (KKT residual),
  ``status`` (the solver's result in words).

``summary.json``: spec path, name, control, steps, converged count, failed steps with
reasons, the last converged step (force, displacement), peak force, wall times.
"""

from __future__ import annotations

import csv
import sys
import time
from pathlib import Path

import equinox as eqx
import jax
import numpy as np

import jaxtube as jt

from .._calibrate.parameters_file import load_law, without_effects_words
from .._data.units import MM_PER_M
from .._json import finite_or_none, write_json
from .common import (
    add_structure_source_arguments,
    bad_output_directory,
    positive_int,
    write_directory,
)
from .dynamics import simulate_spec_dynamics
from .kite_fem import simulate_kite_fem


def _path_of(params, path, *, structure):
    """``jaxtube.solve_path`` with the structure a keyword (static) argument."""
    return jt.solve_path(structure, params, path)


_SOLVE_PATH = jt.stored_jit(_path_of, static_argnames=("structure",))


OUTPUT_FILES = ("path.csv", "force_deflection.png", "deformed_shape.png", "summary.json")
CSV_COLUMNS = (
    "step", "load_factor", "control_displacement_mm", "control_force_N",
    "control_node_dx_mm", "control_node_dy_mm", "control_node_dz_mm",
    "max_moment_Nm", "max_bending_moment_Nm", "joints_wrinkled", "joints_collapsed",
    "worst_regime", "converged", "iterations", "residual", "status",
)


# ------------------------------------------------------------------------------------------
# Parser
# ------------------------------------------------------------------------------------------


def add_simulate(subparsers) -> None:
    parser = subparsers.add_parser(
        "simulate", help="run the load path of a TOML spec and write results",
        description="Load a TOML structure spec, follow its load path and write path.csv, "
                    "force_deflection.png, deformed_shape.png and summary.json into --out.")
    add_structure_source_arguments(
        parser, "instead of a spec: hang a kite_fem model (initial.npz) from its suspension "
                "nodes under gravity and write positions.csv, lines.csv, kite_shape.png, "
                "summary.json (fitting._cli.kite_fem); --steps: gravity steps (default 1)")
    parser.add_argument("--out", type=Path, required=True,
                        help="output directory (created; existing files of the same names "
                             "are replaced, other files are left alone)")
    parser.add_argument("--steps", type=positive_int, default=None,
                        help="number of load steps (overrides [path].steps)")
    parser.add_argument("--params", type=Path, default=None,
                        help="parameters.json of 'jaxtube fit': its fitted bending law replaces "
                             "the bending law of every tube")
    parser.add_argument("--quiet", action="store_true",
                        help="print only problems (failed steps, errors)")
    parser.set_defaults(run=_simulate)


# ------------------------------------------------------------------------------------------
# simulate
# ------------------------------------------------------------------------------------------


class _Reporter:
    def __init__(self, quiet: bool):
        self.quiet = quiet

    def progress(self, message: str) -> None:
        if not self.quiet:
            print(message, file=sys.stderr, flush=True)

    def problem(self, message: str) -> None:
        print(message, file=sys.stderr, flush=True)

    def result(self, message: str) -> None:
        if not self.quiet:
            print(message, flush=True)


def _simulate(args) -> int:
    report = _Reporter(args.quiet)
    started = time.perf_counter()
    out = Path(args.out)
    if bad_output_directory(out):
        return 2
    if (args.spec is None) == (args.kite_fem is None):
        report.problem("error: give either a spec file or --kite-fem NPZ")
        return 2
    if args.kite_fem is not None:
        return simulate_kite_fem(args.kite_fem, out, pressure_bar=args.pressure_bar,
                                 bending_scale=args.bending_scale, steps=args.steps or 1,
                                 quiet=args.quiet)
    try:
        spec = jt.load_spec(args.spec, steps=args.steps)
    except jt.SpecError as error:
        report.problem(f"error: invalid spec\n{error}")
        return 2
    structure, params, path, meta = spec
    if args.params is not None:
        try:
            law = load_law(args.params)
        except ValueError as error:
            report.problem(f"error: {error}")
            return 2
        params = eqx.tree_at(lambda p: p.bending_laws, params,
                             tuple(law for _ in params.bending_laws))
        spec = spec._replace(params=params)
        report.progress(f"bending law of every tube from {args.params}"
                        + without_effects_words(args.params))
    if meta.dynamics is not None:
        return simulate_spec_dynamics(spec, out, quiet=args.quiet)
    joint_node = _joint_nodes(spec)
    target = (f"to {meta.path_values[-1] * MM_PER_M:g} mm" if meta.control == "displacement"
              else f"to load factor {meta.path_values[-1]:g}")
    report.progress(
        f"loaded {args.spec}: {len(structure.tube_names)} tube(s), {structure.node_count} "
        f"nodes, {structure.segment_count} segments, {len(joint_node)} spring joints; "
        f"{meta.control} control of {meta.control_node_ref} along "
        f"{_vector_text(meta.control_direction)} {target} in {meta.steps} steps")
    loaded = time.perf_counter()

    report.progress("compiling the solver (the first run of a structure takes a while) ...")
    # Stored between runs (jaxtube.stored_jit): a second run of the spec skips tracing.
    compiled = _SOLVE_PATH.compile(params, path, structure=structure)
    compiled_at = time.perf_counter()
    report.progress(f"compiled in {compiled_at - loaded:.1f} s; solving {meta.steps} steps ...")
    solution = jax.block_until_ready(compiled(params, path))
    solved_at = time.perf_counter()
    report.progress(f"solved in {solved_at - compiled_at:.2f} s")

    table = path_table(spec, solution, joint_node)
    failed = np.flatnonzero(~table["converged"])
    for line in _failure_lines(table):
        report.problem(line)

    times = {"load_s": loaded - started, "compile_s": compiled_at - loaded,
             "solve_s": solved_at - compiled_at}
    summary = _summary(args, spec, table, times)
    figures = _figures(spec, solution, table, joint_node)
    write_outputs(out, table, figures, summary, started)
    _print_summary(report, table, summary, out)
    if failed.size:
        report.problem(f"warning: {failed.size} of {table['step'].size} steps did not converge "
                       "(marked converged = 0 in path.csv)")
        return 1
    return 0


def _vector_text(vector) -> str:
    return "(" + ", ".join(f"{float(x):.3g}" for x in np.asarray(vector) + 0.0) + ")"


def _joint_nodes(spec: jt.LoadedSpec) -> tuple[int, ...]:
    """Node index of every spring joint, in the order of ``Solution.joint_regime``."""
    return spec.structure.spring_joint_topology().node


def path_table(spec: jt.LoadedSpec, solution: jt.Solution, joint_node) -> dict[str, np.ndarray]:
    """Per-step results as numpy columns (names as in ``CSV_COLUMNS``; SI converted to mm).

    Under force control the control displacement is the path node's displacement along
    the path direction and the control force the applied point force there along it.
    """
    meta, params = spec.metadata, spec.params
    node, direction = meta.control_node, meta.control_direction
    reference = np.asarray(params.node_position)[node]
    moved = np.asarray(solution.node_position)[:, node] - reference  # [K, 3]
    load_factor = np.asarray(solution.load_factor, dtype=float).reshape(-1)
    steps = moved.shape[0]
    if isinstance(spec.path, jt.DisplacementControl):
        displacement = np.asarray(solution.control_displacement, dtype=float)
        force = np.asarray(solution.control_force, dtype=float)
    else:
        displacement = moved @ direction
        applied = float(np.asarray(params.node_force)[node] @ direction)
        force = load_factor * applied
    moment = np.asarray(solution.joint_moment, dtype=float)  # [K, J, 3]
    regime = np.asarray(solution.joint_regime, dtype=int).reshape(steps, -1)
    has_joints = regime.shape[1] > 0
    converged = np.asarray(solution.converged, dtype=bool).reshape(-1)
    codes = np.asarray(solution.result, dtype=int).reshape(-1)
    return {
        "step": np.arange(1, steps + 1),
        "load_factor": np.broadcast_to(load_factor, (steps,)),
        "control_displacement_mm": displacement * MM_PER_M,
        "control_force_N": force,
        "control_node_dx_mm": moved[:, 0] * MM_PER_M,
        "control_node_dy_mm": moved[:, 1] * MM_PER_M,
        "control_node_dz_mm": moved[:, 2] * MM_PER_M,
        "max_moment_Nm": (np.linalg.norm(moment, axis=-1).max(axis=-1) if has_joints
                          else np.zeros(steps)),
        "max_bending_moment_Nm": (np.linalg.norm(moment[..., :2], axis=-1).max(axis=-1)
                                  if has_joints else np.zeros(steps)),
        "joints_wrinkled": (regime == 1).sum(axis=1),
        "joints_collapsed": (regime == 2).sum(axis=1),
        "worst_regime": regime.max(axis=1) if has_joints else np.zeros(steps, dtype=int),
        "converged": converged,
        "iterations": np.asarray(solution.iterations, dtype=int).reshape(-1),
        "residual": np.asarray(solution.residual, dtype=float).reshape(-1),
        "status": np.array([jt.RESULT_MESSAGES.get(int(c), f"unknown result code {int(c)}")
                            for c in codes]),
    }


def _ranges(steps) -> str:
    """``[1, 2, 3, 7]`` -> ``"1-3, 7"``."""
    parts, steps = [], list(steps)
    start = prev = None
    for s in steps + [None]:
        if s is not None and prev is not None and s == prev + 1:
            prev = s
            continue
        if start is not None:
            parts.append(f"{start}" if start == prev else f"{start}-{prev}")
        start = prev = s
    return ", ".join(parts)


def _failure_lines(table) -> list[str]:
    """Non-converged steps in words, grouped by reason."""
    failed = ~table["converged"]
    lines = []
    for message in dict.fromkeys(table["status"][failed]):
        chosen = failed & (table["status"] == message)
        steps = table["step"][chosen]
        worst = np.nanmax(table["residual"][chosen]) if np.any(
            np.isfinite(table["residual"][chosen])) else float("nan")
        plural = "s" if steps.size > 1 else ""
        lines.append(f"step{plural} {_ranges(steps.tolist())} of {table['step'].size} did not "
                     f"converge: {message} (largest KKT residual {worst:.3g})")
    return lines


def _summary(args, spec: jt.LoadedSpec, table, times) -> dict:
    meta = spec.metadata
    converged = table["converged"]
    done = np.flatnonzero(converged)
    final = None
    if done.size:
        k = int(done[-1])
        final = {"step": int(table["step"][k]),
                 "load_factor": finite_or_none(table["load_factor"][k]),
                 "displacement_mm": finite_or_none(table["control_displacement_mm"][k]),
                 "force_N": finite_or_none(table["control_force_N"][k]),
                 "max_moment_Nm": finite_or_none(table["max_moment_Nm"][k]),
                 "worst_regime": int(table["worst_regime"][k])}
    forces = np.where(converged, table["control_force_N"], np.nan)
    peak = int(np.nanargmax(np.abs(forces))) if np.any(np.isfinite(forces)) else None
    return {
        "spec": str(Path(args.spec).resolve()),
        "name": meta.name,
        "description": meta.description,
        "jaxtube_version": jt.__version__,
        "control": meta.control,
        "control_node": meta.control_node_ref,
        "control_direction": meta.control_direction.tolist(),
        "steps": int(table["step"].size),
        "converged_steps": int(converged.sum()),
        "failed_steps": [
            {"step": int(table["step"][k]), "reason": str(table["status"][k]),
             "residual": finite_or_none(table["residual"][k])}
            for k in np.flatnonzero(~converged)],
        "final": final,
        "final_force_N": None if final is None else final["force_N"],
        "final_displacement_mm": None if final is None else final["displacement_mm"],
        "peak_force_N": None if peak is None else finite_or_none(forces[peak]),
        "peak_force_step": None if peak is None else int(table["step"][peak]),
        "wall_time_s": {key: round(value, 3) for key, value in times.items()},
        "outputs": list(OUTPUT_FILES),
    }


def _figures(spec: jt.LoadedSpec, solution: jt.Solution, table, joint_node) -> dict:
    meta, params = spec.metadata, spec.params
    label = meta.name or Path(meta.source).stem
    direction = _vector_text(meta.control_direction)
    deflection = jt.force_deflection_figure(
        table["control_displacement_mm"], table["control_force_N"], table["worst_regime"],
        table["converged"], title=f"{label}: {meta.control} control of "
                                  f"{meta.control_node_ref}",
        xlabel=f"displacement of {meta.control_node_ref} along {direction} [mm]",
        ylabel=f"force along {direction} [N]")
    factors = np.asarray(solution.load_factor, dtype=float).reshape(-1)
    point_force = factors[:, None, None] * np.asarray(params.node_force)[None]
    control = None
    if meta.control == "displacement":
        control = (meta.control_node, meta.control_direction, table["control_force_N"])
    # Line loads scale with the load factor, self-weight does not (jaxtube.scale_loads).
    distributed = (factors[:, None, None] * np.asarray(params.line_load)[None]
                   + (np.asarray(params.mass_per_length)[:, None]
                      * np.asarray(params.gravity)[None])[None])
    shape = jt.deformed_shape_figure(
        spec.structure, np.asarray(params.node_position), np.asarray(solution.node_position),
        table["converged"], joint_node=joint_node, joint_regime=np.asarray(
            solution.joint_regime), point_force=point_force, control=control,
        distributed=distributed, title=label)
    return {"force_deflection.png": deflection, "deformed_shape.png": shape}


def _write_csv(path: Path, table) -> None:
    with open(path, "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(CSV_COLUMNS)
        for k in range(table["step"].size):
            row = []
            for column in CSV_COLUMNS:
                value = table[column][k]
                if column == "converged":
                    row.append(int(bool(value)))
                elif isinstance(value, (float, np.floating)):
                    row.append(f"{float(value):.10g}")
                else:
                    row.append(str(value))
            writer.writerow(row)


def write_outputs(out: Path, table, figures: dict, summary: dict, started: float) -> None:
    """Write the outputs of ``simulate`` atomically (see :func:`write_directory`)."""

    def write_summary(path):
        data = dict(summary)
        data["wall_time_s"] = dict(data["wall_time_s"],
                                   total_s=round(time.perf_counter() - started, 3))
        write_json(path, data)

    writers = {"path.csv": lambda path: _write_csv(path, table)}
    for name, figure in figures.items():
        writers[name] = lambda path, figure=figure: figure.savefig(path, dpi=120)
    writers["summary.json"] = write_summary
    write_directory(out, writers)


def _print_summary(report: _Reporter, table, summary, out: Path) -> None:
    steps = table["step"].size
    rows = np.unique(np.linspace(0, steps - 1, min(steps, 10)).round().astype(int))
    header = (f"{'step':>5} {'load factor':>11} {'displ. [mm]':>11} {'force [N]':>10} "
              f"{'max |M| [N m]':>13} {'wrinkled':>8} {'collapsed':>9}  status")
    lines = [header]
    for k in rows:
        lines.append(
            f"{table['step'][k]:>5d} {table['load_factor'][k]:>11.4g} "
            f"{table['control_displacement_mm'][k]:>11.4g} {table['control_force_N'][k]:>10.4g} "
            f"{table['max_moment_Nm'][k]:>13.4g} {table['joints_wrinkled'][k]:>8d} "
            f"{table['joints_collapsed'][k]:>9d}  {table['status'][k]}")
    final = summary["final"]
    lines.append(f"converged: {summary['converged_steps']} of {steps} steps")
    if final is not None:
        lines.append(f"last converged step {final['step']}: displacement "
                     f"{final['displacement_mm']:.4g} mm, force {final['force_N']:.4g} N")
    if summary["peak_force_N"] is not None:
        lines.append(f"peak force {summary['peak_force_N']:.4g} N at step "
                     f"{summary['peak_force_step']}")
    wall = summary["wall_time_s"]
    lines.append(f"time: compile {wall['compile_s']:.1f} s, solve {wall['solve_s']:.2f} s")
    lines.append(f"wrote {', '.join(OUTPUT_FILES)} to {out}")
    report.result("\n".join(lines))

