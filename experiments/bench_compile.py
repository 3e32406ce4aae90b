"""Compile-time benchmark: how long XLA takes to compile jaxtube's core programs, and why.

Programs (each compiled fresh, the persistent compilation cache off):

- ``solve``: one static solve, ``jt.equilibrium``, of a 10-segment 3-D cantilever (tension-field
  law, tip force 60 % of the wrinkling load; the dense KKT route);
- ``path``: a 10-step displacement-controlled curve of that cantilever, ``jt.solve_path``;
- ``gradient``: the gradient of the tip deflection of ``solve`` w.r.t. the pressure and the
  tip force (the implicit-function-theorem tangent of the solve);
- ``fit``: the calibration's residual-and-Jacobian program on ``tests/data/cantilever_shear.csv``
  (6 curves x 25 points, default pivots; ``jacfwd`` through the path solves);
- ``kite`` (full mode only): one static solve of the stand-in tube kite of
  ``experiments/tube_kite.py`` (24 leading-edge segments, 4 struts; the augmented sparse route).

For each: the time to trace and lower (``jax.jit(f).lower(...)``), the XLA compile time
(``.compile()``), the size of the lowered StableHLO module (operations, lines) and of the
optimised HLO (instructions), medians over fresh compiles (``jax.clear_caches()`` between
them, so every repeat traces, lowers and compiles again), then the warm run time of the
compiled program (median of repeats) and the Newton steps it took. Run from the repository
root::

    python -m experiments.bench_compile            # 3 fresh compiles each, kite included
    python -m experiments.bench_compile --quick    # 1 compile each, no kite

Output is printed and written to ``experiments/results/bench_compile.txt`` (``--out``). The
machine load (``os.getloadavg()``) is printed beside every program: on a shared machine the
times must be read against it.
"""

from __future__ import annotations

import argparse
import datetime
import math
import os
import platform
import re
import time
from pathlib import Path

os.environ.setdefault("JAXTUBE_NO_COMPILATION_CACHE", "1")

import equinox as eqx  # noqa: E402
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import fitting as ft  # noqa: E402
import jaxtube as jt  # noqa: E402
from experiments.profile_batch_pieces import median_seconds  # noqa: E402
from experiments.tube_kite import build_kite  # noqa: E402
from fitting._calibrate import problem as calibrate  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FIT_DATA = ROOT / "tests" / "data" / "cantilever_shear.csv"

LENGTH, RADIUS, PRESSURE, WALL_MODULUS = 1.0, 0.075, 2.0e4, 150.0e3  # m, m, Pa, N/m
SEGMENTS, PATH_STEPS = 10, 10
_OP = re.compile(r"=\s*\"?(stablehlo|chlo|mhlo|func)\.[a-z_]+|^\s*(stablehlo|func)\.[a-z_]+")


def _cantilever(pressure):
    law = jt.TensionFieldLaw(WALL_MODULUS, residual_stiffness_ratio=0.01)
    return jt.cantilever(LENGTH, RADIUS, pressure, SEGMENTS, law, jt.LinearLaw(150.0))


def _with_tip_force(structure, params, force):
    tip = structure.node_id("tube:end")
    return eqx.tree_at(lambda p: p.node_force, params,
                       params.node_force.at[tip].set(jnp.array([0.0, 0.0, -1.0]) * force))


def programs(quick: bool):
    """``name -> (function, arguments, Newton steps of an output)``."""
    structure, params = _cantilever(PRESSURE)
    wrinkling = math.pi * PRESSURE * RADIUS**3 / (2.0 * LENGTH)
    tip = structure.node_id("tube:end")
    loaded = _with_tip_force(structure, params, 0.6 * wrinkling)
    path = jt.DisplacementControl(tip, [0.0, 0.0, -1.0],
                                  jnp.linspace(0.0, 0.3, PATH_STEPS + 1)[1:])

    def solve(p):
        return jt.equilibrium(structure, p)

    def curve(p):
        return jt.solve_path(structure, p, path)

    def tip_deflection(pressure_and_force):
        pressure, force = pressure_and_force[0], pressure_and_force[1]
        p = eqx.tree_at(lambda q: q.pressure, params, jnp.full_like(params.pressure, pressure))
        sol = jt.equilibrium(structure, _with_tip_force(structure, p, force))
        return -sol.node_position[tip, 2], sol.iterations

    def gradient(x):
        return jax.grad(tip_deflection, has_aux=True)(x)

    data = ft.load_measurements(FIT_DATA)
    problem = calibrate.make_problem(data, ft.PivotScaling())
    static = problem.static()
    fit_args = (jnp.asarray(problem.full(problem.base[list(problem.free_index)])),
                *problem.residual_args(None))

    def fit(vector, *args):
        return calibrate._residuals_and_jacobian(vector, *args, **static)

    table = {
        "solve": (solve, (loaded,), lambda out: np.asarray(out.iterations)),
        "path": (curve, (params,), lambda out: np.asarray(out.iterations)),
        "gradient": (gradient, (jnp.array([PRESSURE, 0.6 * wrinkling]),),
                     lambda out: np.asarray(out[1])),
        "fit": (fit, fit_args, lambda out: np.asarray(out[2].iterations)),
    }
    if not quick:
        kite = build_kite(24, 4)
        kite_structure, kite_params = kite.build()
        table["kite"] = (lambda p: jt.equilibrium(kite_structure, p), (kite_params,),
                         lambda out: np.asarray(out.iterations))
    return table


def module_size(lowered) -> tuple[int, int]:
    """``(operations, lines)`` of a lowered program's StableHLO text."""
    text = lowered.as_text()
    lines = text.splitlines()
    return sum(1 for line in lines if _OP.search(line)), len(lines)


def compile_once(fn, args):
    """``(compiled, lower seconds, compile seconds, ops, lines, hlo instructions)``."""
    jax.clear_caches()
    start = time.perf_counter()
    lowered = jax.jit(fn).lower(*args)
    lowered_at = time.perf_counter()
    compiled = lowered.compile()
    done = time.perf_counter()
    ops, lines = module_size(lowered)
    try:
        instructions = sum(1 for line in compiled.as_text().splitlines() if " = " in line)
    except Exception:  # as_text is best effort
        instructions = -1
    return compiled, lowered_at - start, done - lowered_at, ops, lines, instructions


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1 compile each, no kite")
    parser.add_argument("--repeats", type=int, default=None, help="fresh compiles each")
    parser.add_argument("--only", action="append", default=[], help="a program (repeatable)")
    parser.add_argument("--out", type=Path,
                        default=ROOT / "experiments" / "results" / "bench_compile.txt")
    args = parser.parse_args(argv)
    repeats = args.repeats or (1 if args.quick else 3)
    lines = [
        "jaxtube compile-time benchmark (experiments/bench_compile.py"
        + (" --quick" if args.quick else "") + ")",
        f"date {datetime.datetime.now().isoformat(timespec='seconds')}; {platform.machine()}, "
        f"{os.cpu_count()} CPUs; jax {jax.__version__}; persistent cache off; "
        f"{repeats} fresh compile(s) per program",
        "program   | lower s | compile s | StableHLO ops | lines  | HLO instr | warm ms "
        "| Newton steps | load (1 min)",
    ]
    print("\n".join(lines), flush=True)
    for name, (fn, fn_args, steps_of) in programs(args.quick).items():
        if args.only and name not in args.only:
            continue
        runs = [compile_once(fn, fn_args) for _ in range(repeats)]
        compiled = runs[-1][0]
        lower, seconds = (float(np.median([r[k] for r in runs])) for k in (1, 2))
        ops, count, instructions = runs[-1][3:]
        warm = median_seconds(compiled, *fn_args, repeats=5 if name in ("fit", "kite") else 20)
        steps = steps_of(compiled(*fn_args))
        line = (f"{name:9s} | {lower:7.2f} | {seconds:9.2f} | {ops:13d} | {count:6d} | "
                f"{instructions:9d} | {warm * 1e3:7.2f} | {int(np.sum(steps)):12d} | "
                f"{os.getloadavg()[0]:.2f}")
        lines.append(line)
        print(line, flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
