"""Case (c) of ``bench_solver.py``: ``jax.vmap`` of displacement-controlled curves against a
Python loop of single curves, for each solver setting, in the same process.

For every setting (``NewtonKKT`` linear solver, or ``jt.map_members``) two programs are compiled:
the curve under ``vmap`` over a batch of grid members (for ``MAP_MEMBERS``: under
``jt.map_members``, over every device of the process), and the single curve. Each repeat
runs, interleaved over the settings, the batch once and a Python loop of the single curve
over the same members once, so the two are measured under the same machine load. Every
batched member's forces are compared with its single solve.
"""

from __future__ import annotations

import os
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import jaxtube as jt

SETTINGS = {
    "dense": jt.NewtonKKT(linear_solver="dense"),
    "sparse": jt.NewtonKKT(linear_solver="sparse"),
}
#: Not a ``vmap``: ``jt.map_members`` of the default solver's curve, the members split over
#: every device of the process (``--cpu-devices``) and solved one after another on each.
MAP_MEMBERS = "map_members, default solver"


def curve_function(structure, params, control, solver):
    """``(pressure [Pa], radius [m]) -> (control force [K], converged [K], Newton steps [K])``."""

    def curve_at(pressure, radius):
        p = eqx.tree_at(lambda q: (q.pressure, q.node_radius), params,
                        (jnp.full_like(params.pressure, pressure),
                         jnp.full_like(params.node_radius, radius)))
        sol = jt.solve_path(structure, p, control, solver)
        return sol.control_force, sol.converged, sol.iterations

    return curve_at


def measure_batches(report, structure, params, control, grid_p, grid_r, members, repeats,
                    compile_timed, settings=None):
    """Measure every setting; returns ``{name: dict}`` with the warm medians [s] of the batch
    and of the loop, compile times [s], convergence and Newton step counts."""
    settings = ({**SETTINGS, MAP_MEMBERS: jt.NewtonKKT()} if settings is None
                else settings)
    batch = members.size
    batch_p, batch_r = jnp.asarray(grid_p[members]), jnp.asarray(grid_r[members])
    programs = {}
    for name, solver in settings.items():
        fn = curve_function(structure, params, control, solver)
        many = jt.map_members(fn) if name == MAP_MEMBERS else jax.vmap(fn)
        batched, lower_b, compile_b, _ = compile_timed(many, batch_p, batch_r)
        single, lower_s, compile_s, _ = compile_timed(fn, batch_p[0], batch_r[0])
        programs[name] = (batched, single, lower_b + compile_b, lower_s + compile_s)
        report(f"    {name}: compile batched {lower_b + compile_b:.1f} s, single "
               f"{lower_s + compile_s:.1f} s ({load_now()})")
    walls = {name: {"batch": [], "loop": []} for name in settings}
    outputs = {}
    for name, (batched, single, _, _) in programs.items():  # warm-up, and the outputs
        out = jax.block_until_ready(batched(batch_p, batch_r))
        singles = [jax.block_until_ready(single(batch_p[k], batch_r[k])) for k in range(batch)]
        outputs[name] = (out, singles)
    for _ in range(repeats):
        for name, (batched, single, _, _) in programs.items():
            start = time.perf_counter()
            jax.block_until_ready(batched(batch_p, batch_r))
            walls[name]["batch"].append(time.perf_counter() - start)
            start = time.perf_counter()
            for k in range(batch):
                jax.block_until_ready(single(batch_p[k], batch_r[k]))
            walls[name]["loop"].append(time.perf_counter() - start)
    results = {}
    for name, (_, _, compile_batched, compile_single) in programs.items():
        (force, converged, steps), singles = outputs[name]
        force, converged, steps = np.asarray(force), np.asarray(converged), np.asarray(steps)
        single_force = np.stack([np.asarray(s[0]) for s in singles])
        single_steps = np.stack([np.asarray(s[2]) for s in singles])
        difference = np.max(np.abs(force - single_force) / np.maximum(np.abs(single_force),
                                                                       1e-12))
        batch_median = float(np.median(walls[name]["batch"]))
        loop_median = float(np.median(walls[name]["loop"]))
        results[name] = dict(
            batch=batch_median, loop=loop_median, compile_batched=compile_batched,
            compile_single=compile_single, converged=int(converged.all(axis=1).sum()),
            steps=float(steps.sum(axis=1).mean()), lockstep=int(steps.max(axis=0).sum()),
            same_steps=bool(np.array_equal(steps, single_steps)), difference=float(difference))
        report(f"    {name}: batch of {batch} median {batch_median:.2f} s "
               f"({batch_median / batch * 1e3:.0f} ms per curve; runs "
               f"{np.round(walls[name]['batch'], 2).tolist()}), loop of single curves "
               f"{loop_median:.2f} s ({loop_median / batch * 1e3:.0f} ms per curve): batched "
               f"{loop_median / batch_median:.2f}x the loop's throughput")
        lockstep = ("one after another on each device, no lockstep" if name == MAP_MEMBERS
                    else f"{results[name]['lockstep']} in lockstep")
        report(f"      members converged {results[name]['converged']}/{batch}; Newton steps "
               f"{results[name]['steps']:.1f} per curve on average, {lockstep}; batched "
               f"members equal their single solves: forces to "
               f"{difference:.1e} relative, Newton steps "
               f"{'identical' if results[name]['same_steps'] else 'DIFFER'}")
    report(f"    end: {load_now()}")
    return results


def load_now() -> str:
    one, five, _ = os.getloadavg()
    return f"load average {one:.1f} / {five:.1f}"
