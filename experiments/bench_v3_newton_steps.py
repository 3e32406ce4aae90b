"""Benchmark: where do the V3 hang's Newton steps go? Continuations against one step.

One compiled program (``jaxtube.hang_program`` of the V3 kite, one stage, at most 100 Newton
steps per run, restarted from where it stopped until converged); every schedule is a host
loop of calls of it with other parameters (gravity factor, the lines' blend width
``tension_smoothing``, the bending scale), so no schedule compiles anything new. Prints
per schedule: converged, Newton steps per stage and run, seconds, and the largest distance
of its equilibrium from the one-step equilibrium [m] (continuations must reach the same
equilibrium). Breukels 2011 bending law x 0.377 (the committed calibration's point).

    python -m experiments.bench_v3_newton_steps [auto|dense|sparse]

Data: experiments/data/v3_hanging ("Structural model data from awegroup/kite_fem (MIT,
(c) 2025 Patrick Roeleveld)").
"""
import os
import sys
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import jaxtube as jt

MODEL = "experiments/data/v3_hanging/kite_fem/initial.npz"
SCALE = 0.377


def with_(params, gravity_factor=1.0, smoothing=None, factor=None):
    """Parameters at a fraction of gravity, another blend width, another bending scale."""
    p = jt.scale_gravity_and_loads(params, gravity_factor)
    if smoothing is not None:
        p = eqx.tree_at(lambda q: q.elements.tension_smoothing, p, jnp.asarray(smoothing))
    if factor is not None:
        laws = tuple(eqx.tree_at(lambda law: law.factor, law, factor)
                     if isinstance(law, jt.ScaledLaw) else law for law in p.bending_laws)
        p = eqx.tree_at(lambda q: q.bending_laws, p, laws)
    return p


def main():
    route = sys.argv[1] if len(sys.argv) > 1 else "auto"
    imported = jt.import_kite_fem(MODEL, pressure_bar=0.15, bending_scale=SCALE)
    structure, p0 = imported.structure, imported.params
    solver = jt.NewtonKKT(max_steps=100, linear_solver=route)
    started = time.perf_counter()
    program = jax.jit(jt.hang_program(structure, 1, solver)).lower(
        p0, jt.undeformed_start(structure, p0)).compile()
    print(f"route {route}: compile {time.perf_counter() - started:.1f} s; load "
          f"{os.getloadavg()}", flush=True)

    def solve_until(params, start, cap=8):
        runs, t0 = [], time.perf_counter()
        for _ in range(cap):
            sol = jax.block_until_ready(program(params, start))
            runs.append(int(np.asarray(sol.iterations)[-1]))
            if bool(np.asarray(sol.converged)[-1]):
                return sol, runs, time.perf_counter() - t0, True
            start = jt.restart_from(sol)
        return sol, runs, time.perf_counter() - t0, False

    def schedule(name, stages):
        start, total, seconds = jt.undeformed_start(structure, p0), [], 0.0
        for params in stages:
            sol, runs, sec, ok = solve_until(params, start)
            total.append(runs)
            seconds += sec
            start = jt.restart_from(sol)
            if not ok:
                break
        print(f"{name}: converged {ok}; Newton steps per stage (runs) {total} = "
              f"{sum(map(sum, total))}; {seconds:.2f} s; result "
              f"{int(np.asarray(sol.result)[-1])}; load {os.getloadavg()[0]:.1f}", flush=True)
        return np.asarray(sol.node_position)[-1]

    reference = schedule("full gravity, one step", [with_(p0)])
    for name, stages in [
        ("blend widths 1e-2, 1e-3, 1e-4", [with_(p0, 1.0, d) for d in (1e-2, 1e-3, 1e-4)]),
        ("gravity in 4 steps", [with_(p0, f) for f in (0.25, 0.5, 0.75, 1.0)]),
        ("blend widths 3e-2, 3e-3, 1e-4", [with_(p0, 1.0, d) for d in (3e-2, 3e-3, 1e-4)]),
        ("law x 1 then x 0.377", [with_(p0, factor=1.0), with_(p0)]),
    ]:
        found = schedule(name, stages)
        print(f"   largest distance from the one-step equilibrium: "
              f"{float(np.abs(found - reference).max()):.2e} m", flush=True)


if __name__ == "__main__":
    main()
