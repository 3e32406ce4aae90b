"""Benchmark: the TU Delft V3 kite (kite_fem ``initial.npz``) hung from nodes 82 and 116
under gravity, from the undeformed shape to equilibrium (issue 14's speed target: <= 2 s
warm on the 2-core CPU).

Prints the import time, the compile time, the warm median of ``--repeats`` solves (each
from the undeformed shape), the Newton iterations, convergence, the suspension balance and
the node-for-node cross-check against kite_fem's own solved state of case 1
(``states/load_case_1.npz``, ``coords_current``): RMS and largest node distance, reported
as found (nothing is tuned to it). Results go to ``experiments/results/bench_v3_hang.txt``
when ``--write`` is given.

    python -m experiments.bench_v3_hang [--pressure-bar 0.15] [--bending-scale S]
        [--steps K] [--smoothing W1 W2 ...] [--linear-solver auto|dense|sparse|augmented]
        [--baseline ROUTE] [--repeats 5] [--write]

``--baseline ROUTE``: the same hang on another KKT route, compiled and timed in the same
process after the main one, and the ratio of the warm medians (a ratio from one process,
not from runs on different days).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import jax
import numpy as np

import jaxtube as jt

HERE = Path(__file__).parent
MODEL = HERE / "data" / "v3_hanging" / "kite_fem" / "initial.npz"
STATE = HERE / "data" / "v3_hanging" / "kite_fem" / "states" / "load_case_1.npz"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pressure-bar", type=float, default=0.15)
    parser.add_argument("--bending-scale", type=float, default=None)
    parser.add_argument("--steps", type=int, default=1)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--max-steps", type=int, default=None,
                        help="Newton iteration cap (NewtonKKT.max_steps)")
    parser.add_argument("--restarts", type=int, default=8,
                        help="runs of max_steps Newton steps after the first, until converged")
    parser.add_argument("--linear-solver", default="auto",
                        choices=("auto", "dense", "sparse", "augmented"),
                        help="KKT route (NewtonKKT.linear_solver)")
    parser.add_argument("--smoothing", type=float, nargs="+", default=None,
                        help="continuation: the lines' blend width per stage, all at full "
                             "gravity (jaxtube.hang_kite's tension_smoothing); the last one is "
                             "the model's")
    parser.add_argument("--baseline", default=None, choices=("dense", "sparse", "augmented"),
                        help="time the same hang on this KKT route too, in this process")
    parser.add_argument("--write", action="store_true")
    parser.add_argument("--figure", type=Path, default=None,
                        help="write the hung kite's 3-D figure (PNG) here")
    args = parser.parse_args()

    started = time.perf_counter()
    imported = jt.import_kite_fem(MODEL, pressure_bar=args.pressure_bar,
                                  bending_scale=args.bending_scale)
    imported_at = time.perf_counter()
    settings = {} if args.max_steps is None else {"max_steps": args.max_steps}
    schedule = {}
    if args.smoothing:
        schedule = {"load_factors": [1.0] * len(args.smoothing),
                    "tension_smoothing": args.smoothing}

    def timed_hang(route):
        """Compile the hang on a KKT route and time ``--repeats`` warm solves:
        ``(compile seconds, warm times, last solution, runs)``."""
        solver = jt.NewtonKKT(linear_solver=route, **settings)
        t_compile = time.perf_counter()
        hang = jax.jit(jt.hang_program(imported.structure, args.steps, solver, **schedule))
        start = jt.undeformed_start(imported.structure, imported.params)
        compiled = hang.lower(imported.params, start).compile()
        t_compile = time.perf_counter() - t_compile
        print(f"{route} route compiled in {t_compile:.1f} s", flush=True)
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            solution, runs = jt.hang_until_converged(
                imported.structure, imported.params, restarts=args.restarts,
                compiled=compiled, solver=solver)
            jax.block_until_ready(solution)
            times.append(time.perf_counter() - t0)
        return t_compile, times, solution, runs

    compile_seconds, times, solution, runs = timed_hang(args.linear_solver)
    solver = jt.NewtonKKT(linear_solver=args.linear_solver, **settings)
    compiled_at = imported_at + compile_seconds
    baseline = None
    if args.baseline is not None:
        b_compile, b_times, b_solution, b_runs = timed_hang(args.baseline)
        b_gap = float(np.max(np.abs(np.asarray(b_solution.node_position)[-1]
                                    - np.asarray(solution.node_position)[-1])))
        baseline = (
            f"baseline, same process: {args.baseline} route, warm median "
            f"{statistics.median(b_times):.3f} s (min {min(b_times):.3f}, max "
            f"{max(b_times):.3f}), compile {b_compile:.1f} s, runs {b_runs}, Newton iterations "
            f"{np.asarray(b_solution.iterations).tolist()}; {args.linear_solver} is "
            f"{statistics.median(b_times) / statistics.median(times):.2f}x faster; largest "
            f"node distance between the two equilibria {b_gap:.2e} m")
    converged = np.asarray(solution.converged)
    iterations = np.asarray(solution.iterations)
    positions = imported.kite_positions(np.asarray(solution.node_position)[-1])
    reference = jt.read_kite_fem_positions(STATE, node_count=imported.model.node_count)
    distance = np.linalg.norm(positions - reference, axis=1)
    undeformed = np.linalg.norm(imported.model.node_position - reference, axis=1)
    rows = jt.kite_fem_line_table(imported, solution)
    balance = jt.weight_and_reactions(imported, solution)
    counts = {}
    for row in rows:
        counts[(row["element"], row["state"])] = counts.get((row["element"], row["state"]), 0) + 1
    load = os.getloadavg()
    s = imported.structure
    lines = [
        f"V3 kite hung from {imported.suspension} under gravity, {args.pressure_bar} bar, "
        f"bending law: Breukels 2011" + (f" x {args.bending_scale}" if args.bending_scale else ""),
        f"model: {s.segment_count} segments in {len(s.tube_names)} tubes, "
        f"{len(s.elements.point_names)} point nodes ({len(s.elements.fixed_points)} fixed), "
        f"{len(s.elements.attachment_nodes)} attachment points, "
        f"{len(s.elements.line_ends)} lines, {len(s.elements.pulley_ends)} pulleys, "
        f"{balance['total_mass_kg']:.4f} kg",
        f"import {imported_at - started:.2f} s, compile {compiled_at - imported_at:.1f} s",
        f"warm hang (all runs): median {statistics.median(times):.3f} s over {args.repeats} "
        f"(min {min(times):.3f}, max {max(times):.3f}); "
        + (f"{args.steps} gravity step(s)" if not args.smoothing else
           f"full gravity, blend widths {args.smoothing} (continuation)"),
        f"runs of at most {solver.max_steps} Newton steps: {runs}; last run: converged per "
        f"step {converged.tolist()}, Newton iterations {iterations.tolist()}, "
        f"result {[jt.RESULT_MESSAGES.get(int(c), '?') for c in np.asarray(solution.result)]}; "
        f"residual {np.asarray(solution.residual).tolist()}",
        f"weight and loads {np.round(balance['weight_and_loads_N'], 4).tolist()} N; reactions "
        f"sum {np.round(balance['reaction_sum_N'], 4).tolist()} N",
        f"moment balance: applied {np.round(balance['applied_moment_Nm'], 4).tolist()}, "
        f"reactions {np.round(balance['reaction_moment_Nm'], 4).tolist()} N m",
        "lines: " + ", ".join(f"{k[0]} {k[1]} {v}" for k, v in sorted(counts.items())),
        f"against kite_fem's solved case 1 (node for node, 247 nodes): RMS "
        f"{1e3 * np.sqrt(np.mean(distance**2)):.1f} mm, max {1e3 * distance.max():.1f} mm at "
        f"node {int(distance.argmax())}; undeformed vs kite_fem: RMS "
        f"{1e3 * np.sqrt(np.mean(undeformed**2)):.1f} mm, max {1e3 * undeformed.max():.1f} mm",
        f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}; jax {jax.__version__}; "
        f"{args.linear_solver} KKT route",
    ] + ([baseline] if baseline else [])
    if args.figure is not None:

        figure = jt.deformed_shape_figure(
            s, jt.kite_fem_reference_positions(imported), np.asarray(solution.node_position),
            converged,
            line_taut=np.asarray(solution.line_taut),
            pulley_taut=np.asarray(solution.pulley_taut),
            point_mass=np.asarray(imported.params.elements.point_mass),
            gravity=np.asarray(imported.params.gravity), intermediate=0,
            title="V3 kite hung from nodes 82 and 116 (kite_fem frame, gravity down the page)")
        figure.savefig(args.figure, dpi=130)
        np.save(args.figure.with_suffix(".npy"), np.asarray(solution.node_position)[-1])
    text = "\n".join(lines)
    print(text)
    if args.write:
        out = HERE / "results" / "bench_v3_hang.txt"
        out.parent.mkdir(exist_ok=True)
        out.write_text(text + "\n")


if __name__ == "__main__":
    main()
