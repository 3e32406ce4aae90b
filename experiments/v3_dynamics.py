"""The V3 kite's dynamics (issue 37): its first ten natural modes hung at 0.15 and 0.25 bar,
and its response to a sudden centre load.

The kite is the committed V3 model (``experiments/results/v3_model.json``: Breukels' 2011
bending law x ``bending_scale`` fitted to P1_S, the trailing edge's rest lengths x the factor
fitted to P1_TL1) of the campaign ``experiments/data/v3_hanging/campaign.toml``, hung from
its two bridle points under gravity (cases P1_S, 0.15 bar, and P2_S, 0.25 bar) as
``jaxtube shape`` hangs it. The import lumps every mass (tubes' included) on kite_fem's
nodes; the tubes spin with the mass on their nodes (``InertiaParameters.spin_mass_per_length``,
set by :func:`jaxtube.import_kite_fem`).

Usage::

    python -m experiments.v3_dynamics [--out DIR] [--repeats 5] [--duration 0.5]
        [--time-step 0.0025] [--centre-load-kg 2]

Writes to ``DIR`` (default ``experiments/results/v3_dynamics``):

- ``modes_<case>.csv`` (``jaxtube modes``'s columns) and ``mode_shapes_<case>.png`` (the
  first six of the ten);
- ``response.csv``: ``time_s``, the centre node's displacement ``d{x,y,z}_mm`` from the
  hung shape, ``kinetic_energy_J``, ``converged``, ``newton_iterations``, after a dead
  weight of ``--centre-load-kg`` appears at the centre node at t = 0 (0.15 bar, undamped),
  and ``response.png`` (the V3 case P1_PL1's 9.7 kg at 5 ms steps does not converge past
  0.49 s: docs/dynamics.md);
- ``summary.json``: frequencies, the modal analysis's warm seconds (median of ``--repeats``
  runs of the compiled program), the response's wall seconds (warm: the second run of the
  compiled program) and its real-time factor.

The last line states the modal analysis's warm time and the real-time factor.
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import fitting  # noqa: E402
import jaxtube as jt  # noqa: E402
from fitting._cli.modes import MODE_COLUMNS, mode_rows, mode_shapes_figure  # noqa: E402

HERE = Path(__file__).resolve().parent
CAMPAIGN = HERE / "data" / "v3_hanging" / "campaign.toml"
MODEL = HERE / "results" / "v3_model.json"
CASES = ("P1_S", "P2_S")  # hung under gravity alone at 0.15 and 0.25 bar
CENTRE_NODE = 29  # kite_fem's centre node of the V3 test (the README of data/v3_hanging)
MODE_COUNT = 10


def hung_kite(solver: fitting.CaseSolver, case, model):
    """``(imported kite, its hung equilibrium)`` for ``case``."""
    solved = solver.solve(case, model)
    if not solved.converged:
        raise RuntimeError(f"{case.name}: the hang did not converge")
    last = jax.tree_util.tree_map(lambda leaf: leaf[-1], solved.solution)
    return solved.imported, last


def timed_modes(structure, params, solution, repeats: int):
    """The first ``MODE_COUNT`` modes and the warm seconds of each of ``repeats`` runs."""
    program = eqx.filter_jit(lambda p, s: jt.modes(structure, p, s, count=MODE_COUNT))
    modes = jax.block_until_ready(program(params, solution))
    seconds = []
    for _ in range(repeats):
        started = time.perf_counter()
        jax.block_until_ready(program(params, solution))
        seconds.append(time.perf_counter() - started)
    return modes, seconds


def write_csv(path: Path, columns, rows) -> None:
    with open(path, "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)


def centre_response(imported, hung, load_kg: float, time_step: float, duration: float):
    """The response to ``load_kg``'s weight appearing at the centre node at t = 0:
    ``(history, warm wall seconds)``."""
    structure, params = imported.structure, imported.params
    node = int(imported.node_index[CENTRE_NODE])
    force = load_kg * params.gravity
    pattern = jnp.zeros_like(params.node_force)
    if node >= pattern.shape[0]:
        raise ValueError(f"kite_fem node {CENTRE_NODE} is not a tube node of this import")
    load = jt.DynamicLoad(node_force=pattern.at[node].add(force),
                          time_function=jt.StepFunction())
    steps = int(round(duration / time_step))
    history = jax.block_until_ready(jt.simulate_dynamics(
        structure, params, time_step, steps, initial=hung, loads=(load,)))
    started = time.perf_counter()
    history = jax.block_until_ready(jt.simulate_dynamics(
        structure, params, time_step, steps, initial=hung, loads=(load,)))
    return history, time.perf_counter() - started, node


def response_figure(times, motion, history):
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
    for k, axis in enumerate("xyz"):
        top.plot(times, motion[:, k], label=f"d{axis}")
    top.set_ylabel(f"centre node {CENTRE_NODE} displacement [mm]")
    top.legend(fontsize=8)
    bottom.plot(times, np.asarray(history.kinetic_energy))
    bottom.set_xlabel("time [s]")
    bottom.set_ylabel("kinetic energy [J]")
    figure.suptitle("V3 kite at 0.15 bar: a sudden centre load")
    figure.tight_layout()
    return figure


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE / "results" / "v3_dynamics")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--duration", type=float, default=0.5, help="response [s]")
    parser.add_argument("--time-step", type=float, default=0.0025, help="[s]")
    parser.add_argument("--centre-load-kg", type=float, default=2.0)
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    campaign = fitting.read_campaign(CAMPAIGN)
    model = fitting.read_model_file(MODEL, campaign)
    solver = fitting.CaseSolver(campaign)
    cases = {case.name: case for case in campaign.cases}
    summary = {"model": str(MODEL.relative_to(HERE.parent)), "cases": {}}
    hung = {}
    for name in CASES:
        imported, solution = hung_kite(solver, cases[name], model)
        hung[name] = imported, solution
        modes, seconds = timed_modes(imported.structure, imported.params, solution,
                                     args.repeats)
        rows = mode_rows(modes)
        write_csv(args.out / f"modes_{name}.csv", MODE_COLUMNS, rows)
        figure = mode_shapes_figure(
            imported.structure, np.asarray(solution.node_position), modes,
            f"V3 kite hung at {cases[name].pressure_bar} bar ({name}): natural modes")
        figure.savefig(args.out / f"mode_shapes_{name}.png", dpi=110)
        plt.close(figure)
        summary["cases"][name] = {
            "pressure_bar": cases[name].pressure_bar,
            "frequency_Hz": [float(f) for f in np.asarray(modes.frequency)],
            "kind": [row["kind"] for row in rows],
            "modes_seconds_warm": seconds,
            "modes_seconds_warm_median": float(np.median(seconds))}
        print(f"{name}: first modes " + ", ".join(r["frequency_Hz"] for r in rows[:5])
              + f" Hz; modal analysis {np.median(seconds):.3g} s warm (median of "
              f"{len(seconds)})", flush=True)

    imported, solution = hung["P1_S"]
    history, wall, node = centre_response(imported, solution, args.centre_load_kg,
                                          args.time_step, args.duration)
    times = np.asarray(history.time)
    motion = 1e3 * (np.asarray(history.node_position)[:, node]
                    - np.asarray(solution.node_position)[node])
    converged = np.asarray(history.converged)
    rows = [{"time_s": f"{t:.6g}", "dx_mm": f"{m[0]:.6g}", "dy_mm": f"{m[1]:.6g}",
             "dz_mm": f"{m[2]:.6g}", "kinetic_energy_J": f"{e:.6g}", "converged": int(c),
             "newton_iterations": int(i)}
            for t, m, e, c, i in zip(times, motion, np.asarray(history.kinetic_energy),
                                     converged, np.asarray(history.iterations))]
    write_csv(args.out / "response.csv", list(rows[0]), rows)
    figure = response_figure(times, motion, history)
    figure.savefig(args.out / "response.png", dpi=110)
    plt.close(figure)
    factor = args.duration / wall
    summary["response"] = {
        "case": "P1_S", "centre_load_kg": args.centre_load_kg, "time_step_s": args.time_step,
        "duration_s": args.duration, "steps_converged": int(converged.sum()),
        "steps": int(converged.size), "wall_seconds_warm": wall, "real_time_factor": factor,
        "peak_centre_displacement_mm": float(np.linalg.norm(motion, axis=1).max())}
    with open(args.out / "summary.json", "w") as file:
        json.dump(summary, file, indent=2, allow_nan=False)
        file.write("\n")
    medians = ", ".join(f"{name} {summary['cases'][name]['modes_seconds_warm_median']:.3g} s"
                        for name in CASES)
    print(f"V3 modal analysis warm (median): {medians}; sudden centre load: "
          f"{int(converged.sum())}/{converged.size} steps converged, real-time factor "
          f"{factor:.3g} ({args.duration} s simulated in {wall:.3g} s)")
    return 0 if converged.all() else 1


if __name__ == "__main__":
    raise SystemExit(main())
