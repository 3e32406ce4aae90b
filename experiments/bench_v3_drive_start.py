"""Benchmark: where the drive of a V3 centre load starts, the gravity hang or the model file.

The campaign's ``"drive"`` route (``fitting/_campaign/solve.py``) reaches a hanging mass by
:func:`jaxtube.drive_to_dead_load`. Two starts, each one compiled program per node, on the
four centre-load cases of ``experiments/data/v3_hanging/campaign.toml`` with the diagnosis'
model (``results/v3_shape_diagnose/model.json``, the model ``predict`` runs) and the plain
model (the diagnosis' first fits):

- ``gravity first``: the kite hung under gravity (the mass taken off, one solve from the
  undeformed shape), the drive from that equilibrium;
- ``from the model file``: the drive from the undeformed shape (``initial=None``), whose
  first controlled solve is the gravity hang with the mass's node held where the model file
  has it (the route today).

Per case and start: the warm seconds (median of ``--repeats``, the two starts alternating in
one process), the Newton steps in all (hang, controlled solves, dead-load solve), and the
largest distance between the two starts' equilibria [mm].

    python -m experiments.bench_v3_drive_start [--repeats 3]

Writes ``experiments/results/bench_v3_drive_start.txt``. Data: experiments/data/v3_hanging
("Structural model data from awegroup/kite_fem (MIT, (c) 2025 Patrick Roeleveld)").
"""

import argparse
import os
import statistics
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import fitting
import jaxtube as jt

ROOT = Path(__file__).resolve().parent
CAMPAIGN = ROOT / "data" / "v3_hanging" / "campaign.toml"
MODEL = ROOT / "results" / "v3_shape_diagnose" / "model.json"


def starts(structure, node, campaign):
    """``{start: function(params) -> (Newton steps in all, dead-load Solution)}``."""
    solver = jt.NewtonKKT(max_steps=campaign.hang.max_newton_steps)
    drive = dict(solver=solver, steps=campaign.hang.drive_steps,
                 max_increment=campaign.hang.drive_increment_m)

    def gravity_first(params):
        gravity_only = jt.with_node_dead_load(structure, params, node, jnp.zeros(3))
        hung = jt.hang_kite(structure, gravity_only, solver=solver, load_factors=(1.0,))
        driven = jt.drive_to_dead_load(structure, params, node, params.gravity,
                                       initial=jax.tree_util.tree_map(lambda x: x[-1], hung),
                                       **drive)
        return (jnp.sum(hung.iterations) + driven.start.iterations
                + jnp.sum(driven.path.iterations) + driven.equilibrium.iterations,
                driven.equilibrium)

    def from_model_file(params):
        driven = jt.drive_to_dead_load(structure, params, node, params.gravity, **drive)
        return (driven.start.iterations + jnp.sum(driven.path.iterations)
                + driven.equilibrium.iterations, driven.equilibrium)

    return {"gravity first": jax.jit(gravity_first),
            "from the model file": jax.jit(from_model_file)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    campaign = fitting.read_campaign(CAMPAIGN)
    models = {"diagnosis' model": fitting.read_model_file(MODEL, campaign),
              "plain model": fitting.KiteModel()}
    lines = [f"V3 centre loads by displacement control of the mass's node; {args.repeats} "
             f"repeats (median warm seconds, the starts alternating); load average "
             f"{os.getloadavg()[0]:.2f}"]
    programs, totals = {}, {}
    for case in [c for c in campaign.cases if c.route == "drive"]:
        for model_name, model in models.items():
            imported = fitting.import_campaign_case(campaign, case, model)
            node = int(imported.node_index[case.loads[0].node])
            if node not in programs:
                programs[node] = starts(imported.structure, node, campaign)
            seconds = {name: [] for name in programs[node]}
            outcome = {}
            for _ in range(args.repeats + 1):  # the first pass compiles
                for name, program in programs[node].items():
                    started = time.perf_counter()
                    steps, equilibrium = jax.block_until_ready(program(imported.params))
                    seconds[name].append(time.perf_counter() - started)
                    outcome[name] = (int(steps), bool(equilibrium.converged),
                                     np.asarray(equilibrium.node_position))
            positions = [x for _, _, x in outcome.values()]
            distance = 1e3 * float(np.max(np.abs(positions[0] - positions[1])))
            cells = []
            for name, (steps, converged, _) in outcome.items():
                median = statistics.median(seconds[name][1:])
                totals.setdefault((model_name, name), []).append(median)
                cells.append(f"{name}: {median:.2f} s, {steps} Newton steps, converged "
                             f"{converged}")
            lines.append(f"{case.name}, {model_name}: " + "; ".join(cells)
                         + f"; the equilibria {distance:.1e} mm apart")
            print(lines[-1], flush=True)
    lines += [f"in all, {model_name}, {name}: {sum(values):.2f} s"
              for (model_name, name), values in totals.items()]
    text = "\n".join(lines) + f"\nload average at the end {os.getloadavg()[0]:.2f}\n"
    print(text)
    (ROOT / "results" / "bench_v3_drive_start.txt").write_text(text)


if __name__ == "__main__":
    main()
