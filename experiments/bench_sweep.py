"""Sweep benchmark: ``fitting.sweep`` over a pressure x radius grid on this CPU.

Grid: 100 pressures (0.1-0.5 bar) x 100 radii (30-150 mm) = 10,000 points, 1 m cantilever,
12 segments, tension-field law (E t = 150 kN/m), tip load 20 N. The sweep takes the planar
route (a bare law; ``fitting._bench.planar``: fixed Newton steps on the statics of the
chain). Reported: the compile time of one chunk program, the wall time of the whole grid
(all chunks, measured, not projected) as the median of ``--repeats`` warm runs, points per
second, and two baselines in the same process:

- the generic route (``jaxtube.equilibrium`` of the 3-D chain inside the load iterations,
  as every sweep ran before the planar route; still the route of models with effects): one
  chunk program compiled, ``--generic-chunks`` warm chunks timed, projected to the grid;
- a Python loop of single-point planar solves (the same per-point function jitted without
  ``vmap``) on ``--loop-points`` points, projected to the grid.

The XLA CPU kernels are single-threaded (as in the tests; set before JAX starts). The
machine may be shared: the load average at the start and after each phase is printed.

    python -m experiments.bench_sweep            # 3 warm repeats, 2 generic chunks
    python -m experiments.bench_sweep --quick    # 1 warm repeat, 1 generic chunk

Results are printed and written to ``experiments/results/bench_sweep.txt`` (``--out``).
"""

from __future__ import annotations

import os

_SINGLE_THREAD = "--xla_cpu_multi_thread_eigen=false"
if "xla_cpu_multi_thread_eigen" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " " + _SINGLE_THREAD).strip()
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import functools  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import equinox as eqx  # noqa: E402
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import fitting  # noqa: E402
import jaxtube as jt  # noqa: E402
from fitting._bench.rig import TubeModel  # noqa: E402
from fitting._sweep.status import STATUS_MOMENT_MISSED, STATUS_SOLVER_FAILED  # noqa: E402
from fitting._sweep.sweep import _compiled_chunk, _planar_point  # noqa: E402

TARGET_S = 20.0
TIP_LOAD = 20.0  # [N]
BAD = (STATUS_SOLVER_FAILED, STATUS_MOMENT_MISSED)


def _failed(out) -> np.ndarray:
    return (np.isin(np.asarray(out["wrinkling_status"]), BAD)
            | np.isin(np.asarray(out["collapse_status"]), BAD)
            | np.isin(np.asarray(out["deflection_status"]), BAD))


def main() -> None:
    args = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    args.add_argument("--quick", action="store_true")
    args.add_argument("--repeats", type=int, default=3)
    args.add_argument("--chunk-size", type=int, default=fitting.SweepSettings().chunk_size)
    args.add_argument("--generic-chunk-size", type=int, default=128)
    args.add_argument("--generic-chunks", type=int, default=2)
    args.add_argument("--loop-points", type=int, default=200)
    args.add_argument("--out", type=Path,
                      default=Path(__file__).resolve().parent / "results" / "bench_sweep.txt")
    args = args.parse_args()
    if args.quick:
        args.repeats, args.generic_chunks = 1, 1
    lines = []

    def say(text=""):
        print(text, flush=True)
        lines.append(text)

    def load() -> str:
        return f"load average {os.getloadavg()[0]:.1f}"

    law = jt.TensionFieldLaw(150e3)
    settings = fitting.SweepSettings(chunk_size=args.chunk_size)
    pressure, radius = np.meshgrid(np.linspace(0.1e5, 0.5e5, 100), np.linspace(0.03, 0.15, 100),
                                   indexing="ij")
    pressure, radius = pressure.reshape(-1), radius.reshape(-1)
    count = pressure.size
    say(f"bench_sweep: {count} grid points (100 pressures 0.1-0.5 bar x 100 radii 30-150 mm), "
        f"L = 1 m, {settings.segments} segments, tension-field law E t = 150 kN/m, tip load "
        f"{TIP_LOAD:g} N")
    say(f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs (shared with "
        f"other work: {load()} at start), XLA_FLAGS={os.environ['XLA_FLAGS']}, jax "
        f"{jax.__version__}")

    # Planar route: compile, then the whole grid through fitting.sweep, warm.
    say(f"planar route (chunks of {settings.chunk_size}; Newton steps "
        f"{settings.planar_wrinkling_steps}/{settings.planar_collapse_steps}/"
        f"{settings.planar_deflection_steps} for wrinkling/collapse/deflection):")
    compiled, _ = _compiled_chunk(settings, tuple(jax.devices()), "planar")
    size = settings.chunk_size
    chunk = [np.asarray(a[:size]) for a in (pressure, radius, np.ones(count),
                                            np.full(count, TIP_LOAD))]
    start = time.perf_counter()
    compiled.lower(law, *chunk).compile()
    say(f"  compile (one chunk program): {time.perf_counter() - start:.1f} s")
    first = fitting.sweep(law, pressure, radius, 1.0, TIP_LOAD, settings)
    cap = (settings.planar_wrinkling_steps + settings.planar_collapse_steps
           + settings.planar_deflection_steps)
    say(f"  first run (with its compilation): {first.seconds:.1f} s; failed points "
        f"{first.failed_count} of {count}; Newton steps per point (at most {cap}): mean "
        f"{first.iterations.mean():.1f}, max {first.iterations.max()}")
    times = []
    for k in range(args.repeats):
        result = fitting.sweep(law, pressure, radius, 1.0, TIP_LOAD, settings)
        times.append(result.seconds)
        assert result.failed_count == first.failed_count
        say(f"  warm run {k + 1}/{args.repeats}: {result.seconds:.2f} s ({load()})")
    whole = float(np.median(times))
    rate = count / whole
    say(f"  warm: median {whole:.2f} s for all {count} points (measured) = {rate:.0f} points/s")
    say(f"  target <= {TARGET_S:g} s warm for 10,000 points: "
        f"{'met' if whole <= TARGET_S else 'MISSED'} ({whole / TARGET_S:.2f} of the budget)")

    # Baseline 1: a Python loop of single-point planar solves (jit without vmap).
    single = jax.jit(functools.partial(_planar_point, law, settings))
    single(pressure[0], radius[0], 1.0, TIP_LOAD)["iterations"].block_until_ready()
    few = np.linspace(0, count - 1, args.loop_points).astype(int)
    start = time.perf_counter()
    for i in few:
        single(pressure[i], radius[i], 1.0, TIP_LOAD)["iterations"].block_until_ready()
    loop_rate = few.size / (time.perf_counter() - start)
    say(f"baseline, Python loop of single-point planar solves ({few.size} points): "
        f"{loop_rate:.0f} points/s (10,000 points ~{count / loop_rate:.0f} s, projected); "
        f"the vmap chunks are {rate / loop_rate:.1f}x that ({load()})")

    # Baseline 2: the generic route (3-D Newton-KKT solves in the load iterations).
    model = TubeModel(law, effects=())
    generic, _ = _compiled_chunk(settings, tuple(jax.devices()), "generic")
    gsize = args.generic_chunk_size
    inputs = [np.asarray(a[:gsize]) for a in (pressure, radius, np.ones(count),
                                              np.full(count, TIP_LOAD))]
    start = time.perf_counter()
    executable = generic.lower(model, *inputs).compile()
    say(f"baseline, generic route (chunks of {gsize}): compile {time.perf_counter() - start:.1f} s")
    gtimes, deviation, worst_point = [], [], (0.0, None, None, None)
    for k in range(args.generic_chunks):
        sl = slice(k * (count // max(args.generic_chunks, 1)), None)
        inputs = [np.resize(a[sl][:gsize], gsize) for a in (pressure, radius, np.ones(count),
                                                             np.full(count, TIP_LOAD))]
        start = time.perf_counter()
        out = jax.block_until_ready(executable(model, *inputs))
        gtimes.append(time.perf_counter() - start)
        planar = jax.block_until_ready(
            _compiled_chunk(settings, tuple(jax.devices()), "planar")[0](law, *inputs))
        ok = ~_failed(out) & ~_failed(planar)
        for name in ("wrinkling_load", "collapse_load", "tip_deflection"):
            a, b = np.asarray(out[name])[ok], np.asarray(planar[name])[ok]
            deviation.append((name, float(np.max(np.abs(a / b - 1)))))
            if name == "wrinkling_load" and deviation[-1][1] > worst_point[0]:
                i = int(np.argmax(np.abs(a / b - 1)))
                worst_point = (deviation[-1][1], inputs[0][ok][i], inputs[1][ok][i],
                               (a[i], b[i], float(np.asarray(out["wrinkling_moment"])[ok][i])))
        say(f"  chunk {k + 1}/{args.generic_chunks}: {gtimes[-1]:.2f} s, mean Newton steps per "
            f"point {np.mean(np.asarray(out['iterations'])):.1f}, failed "
            f"{int(_failed(out).sum())} of {gsize} ({load()})")
    generic_rate = gsize / float(np.median(gtimes))
    worst = {}
    for name, value in deviation:
        worst[name] = max(worst.get(name, 0.0), value)
    say(f"  {generic_rate:.1f} points/s (10,000 points ~{count / generic_rate:.0f} s, "
        f"projected from the median chunk); the planar route is {rate / generic_rate:.0f}x "
        "that")
    say("  largest relative difference generic vs planar on those chunks: "
        + ", ".join(f"{name} {value:.1e}" for name, value in worst.items())
        + " (the generic load iteration stops at |M_root / M - 1| <= 1e-6)")
    if worst_point[1] is not None:
        # Which route is right: an independent static solve of a separately built
        # cantilever (jaxtube.equilibrium, default solver) at each route's wrinkling load.
        value, p, r, (generic_load, planar_load, moment) = worst_point
        structure, params = jt.cantilever(1.0, r, p, settings.segments, law)
        tip = structure.node_id("tube:end")

        @jax.jit
        def root_moment(load):
            force = params.node_force.at[tip].set(jnp.stack([0.0, 0.0, -load]))
            sol = jt.equilibrium(structure, eqx.tree_at(lambda q: q.node_force, params, force))
            return sol.converged, jnp.linalg.norm(sol.joint_moment[0, :2])

        for route, load in (("generic", generic_load), ("planar", planar_load)):
            converged, m = root_moment(float(load))
            say(f"  at the largest wrinkling-load difference ({value:.1e}; p = {p * 1e-5:.3f} "
                f"bar, r = {r * 1e3:.1f} mm): a single static solve at the {route} load "
                f"{float(load):.6g} N has root moment / M_w - 1 = {float(m) / moment - 1:.1e} "
                f"(converged {bool(converged)})")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
