"""Sweep benchmark: ``fitting.sweep`` over a pressure x radius grid on this CPU.

Grid: 100 pressures (0.1-0.5 bar) x 100 radii (30-150 mm) = 10,000 points, 1 m cantilever,
12 segments, tension-field law (E t = 150 kN/m), tip load 20 N; per point 15 equilibrium
solves (4 tip-load steps, 3 wrinkling and 6 collapse Newton iterations on the root
moment... see ``fitting._sweep``). Reported: compile time (``lower().compile()`` of one
chunk), warm time per chunk (median over the chunks), points per second, the projected or
measured time of the whole grid, and a baseline in the same process: a Python loop of the
same per-point function jitted *without* ``vmap`` on a few points, scaled to the grid.

    python experiments/bench_sweep.py            # all 10,000 points (long on 2 cores)
    python experiments/bench_sweep.py --quick    # 2 warm chunks, projected to 10,000

Results are printed and written to ``experiments/results/bench_sweep.txt`` (``--out``).
"""

from __future__ import annotations

import argparse
import functools
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

try:
    import jaxtube as jt
except ModuleNotFoundError:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import jaxtube as jt

import jax

import fitting
from fitting._rig import TubeModel
from fitting._sweep import _compiled_chunk, _point

TARGET_S = 20.0


def main() -> None:
    args = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    args.add_argument("--quick", action="store_true")
    args.add_argument("--chunk-size", type=int, default=512)
    args.add_argument("--out", type=Path,
                      default=Path(__file__).resolve().parent / "results" / "bench_sweep.txt")
    args = args.parse_args()
    lines = []

    def say(text=""):
        print(text, flush=True)
        lines.append(text)

    law = jt.TensionFieldLaw(150e3)
    settings = fitting.SweepSettings(chunk_size=args.chunk_size)
    pressure, radius = np.meshgrid(np.linspace(0.1e5, 0.5e5, 100), np.linspace(0.03, 0.15, 100),
                                   indexing="ij")
    pressure, radius = pressure.reshape(-1), radius.reshape(-1)
    count = pressure.size
    say(f"bench_sweep: {count} grid points, chunk {settings.chunk_size}, {settings.segments} "
        f"segments; {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
        f"load average {os.getloadavg()[0]:.1f} at start; jax {jax.__version__}")

    compiled, _ = _compiled_chunk(settings, tuple(jax.devices()))
    size = settings.chunk_size
    chunk = [np.asarray(a[:size]) for a in (pressure, radius, np.ones(count), np.full(count, 20.0))]
    model = TubeModel(law)
    start = time.perf_counter()
    executable = compiled.lower(model, *chunk).compile()
    compile_s = time.perf_counter() - start
    say(f"compile (one chunk program): {compile_s:.1f} s")

    chunks = 2 if args.quick else -(-count // size)
    times, failed = [], 0
    for k in range(chunks):
        sl = slice(k * size, (k + 1) * size)
        inputs = [np.resize(a[sl], size) for a in (pressure, radius, np.ones(count),
                                                   np.full(count, 20.0))]
        start = time.perf_counter()
        out = jax.block_until_ready(executable(model, *inputs))
        times.append(time.perf_counter() - start)
        failed += int(np.sum(np.isin(np.asarray(out["collapse_status"]), (2, 3))
                             | np.isin(np.asarray(out["wrinkling_status"]), (2, 3))
                             | (np.asarray(out["deflection_status"]) == 2)))
        say(f"  chunk {k + 1}/{chunks}: {times[-1]:.2f} s, mean Newton steps per point "
            f"{np.mean(np.asarray(out['iterations'])):.1f}, load average "
            f"{os.getloadavg()[0]:.1f}")
    per_chunk = float(np.median(times))
    rate = size / per_chunk
    whole = count / rate
    kind = "projected from the median chunk" if args.quick else "measured (sum of chunks)"
    if not args.quick:
        whole = float(np.sum(times))
    say(f"warm: median {per_chunk:.2f} s per chunk of {size} = {rate:.1f} points/s; "
        f"10,000 points {whole:.0f} s ({kind}); failed points {failed} of {chunks * size}")
    say(f"target <= {TARGET_S:g} s warm: {'met' if whole <= TARGET_S else 'MISSED'} "
        f"({whole / TARGET_S:.0f}x)")

    # Baseline: the same per-point function, jitted without vmap, in a Python loop.
    single = jax.jit(functools.partial(_point, model, settings))
    single(pressure[0], radius[0], 1.0, 20.0)["iterations"].block_until_ready()
    few = np.linspace(0, count - 1, 8).astype(int)
    start = time.perf_counter()
    for i in few:
        single(pressure[i], radius[i], 1.0, 20.0)["iterations"].block_until_ready()
    loop_rate = few.size / (time.perf_counter() - start)
    say(f"baseline: Python loop of single-point solves, {loop_rate:.1f} points/s "
        f"(10,000 points ~{count / loop_rate:.0f} s); vmap chunks are "
        f"{rate / loop_rate:.2f}x that")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
