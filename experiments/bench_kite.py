"""Kite benchmark: the force-deflection curve of a tube kite, warm run time and compile time.

The kite: a leading-edge arc (span 2.6 m, arc height 1.0 m, double taper 85 -> 45 mm,
0.25 bar) with 6 struts (0.3 bar, tapered 55 -> 28 mm, 0.7 m chord), 20 segments each
(140 segments in all), clamped at both wing tips; the crown is pushed down 140 mm in 40
displacement-controlled steps, through wrinkling. Law: the spline sampled from the
tension-field tube, E t = 150 kN/m. Baseline, in the same process: the leading edge alone
(20 segments, the same path). Target: the kite curve in at most 0.5 s warm (issue 13; 2 s before).

This is a script, not a test. Run from the repository root::

    python -m experiments.bench_kite            # 5 repeats
    python -m experiments.bench_kite --quick    # 2 repeats

On a shared 2-core machine, multi-threaded BLAS and Eigen oversubscribe the cores and the
dense KKT solve slows down many times; single-threaded runs are measured with::

    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 \
    XLA_FLAGS="--xla_cpu_multi_thread_eigen=false" \
    python -m experiments.bench_kite

Writes ``experiments/results/bench_kite.txt`` (``--out``). Timings are medians of warm
(compiled) calls; compile times come from ``jax.jit(f).lower(...).compile()``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import jaxtube as jt
from experiments.bench_solver import Report, load_text, time_warm

SEGMENTS = 20
STRUTS = 6
STEPS = 40
MAX_DEFLECTION = 0.14  # m
TARGET = 0.5  # s (issue 13)


def kite(struts: int) -> jt.TubeKite:
    law = jt.SplineLaw.from_tension_field(150e3, 2.5e4, 0.085)
    fractions = (np.arange(struts) + 1.0) / (struts + 1.0)
    return jt.TubeKite(
        segments=SEGMENTS, radius=jt.double_taper(0.085, 0.045), pressure=2.5e4,
        bending_law=law, torsion_law=jt.LinearLaw(150.0), span=2.6, arc_height=1.0,
        struts=tuple(jt.Strut(float(f), 0.7, ((0.0, 0.055), (1.0, 0.028)), SEGMENTS,
                              pressure=3e4) for f in fractions))


def curve_case(struts: int):
    model = kite(struts)
    structure, params = model.build(gravity=(0.0, 0.0, 0.0))
    crown = structure.node_id(model.node("le:centre"))
    path = jt.DisplacementControl(crown, [0.0, 0.0, -1.0],
                                  jnp.linspace(0.0, MAX_DEFLECTION, STEPS + 1)[1:])
    return structure, params, path


def run(report: Report, repeats: int) -> None:
    report(f"jaxtube kite benchmark; {load_text()}")
    threads = {key: os.environ.get(key, "unset") for key in
               ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "XLA_FLAGS")}
    report("threads: " + ", ".join(f"{key}={value!r}" for key, value in threads.items()))
    results = {}
    for label, struts in (("leading edge alone (baseline)", 0), ("kite, LE + 6 struts", STRUTS)):
        structure, params, path = curve_case(struts)
        solve = jax.jit(lambda p, c, structure=structure: jt.solve_path(structure, p, c))
        started = time.perf_counter()
        compiled = solve.lower(params, path).compile()
        compile_s = time.perf_counter() - started
        timing, solution = time_warm(compiled, params, path, repeats=repeats)
        converged = np.asarray(solution.converged)
        force = np.asarray(solution.control_force)
        iterations = int(np.sum(solution.iterations))
        results[label] = timing
        report(f"{label}: {structure.segment_count} segments, {STEPS} steps; compile "
               f"{compile_s:.1f} s; warm {timing.text(1.0, 's')}")
        report(f"  converged {int(converged.sum())}/{converged.size} steps, {iterations} "
               f"Newton steps ({1e3 * timing.median / max(iterations, 1):.1f} ms each); "
               f"peak force {force.max():.1f} N, final {force[-1]:.1f} N; worst regime "
               f"{int(np.max(solution.joint_regime))}")
    base, full = results["leading edge alone (baseline)"], results["kite, LE + 6 struts"]
    report(f"ratio kite / leading edge: {full.median / base.median:.1f}x "
           f"(segments {7 * SEGMENTS} / {SEGMENTS} = 7x)")
    verdict = "met" if full.median <= TARGET else f"missed, {full.median / TARGET:.1f}x"
    report(f"target <= {TARGET:g} s warm for the kite curve: {verdict}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 repeats instead of 5")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent
                        / "results" / "bench_kite.txt")
    args = parser.parse_args(argv)
    report = Report()
    run(report, repeats=2 if args.quick else 5)
    report.write(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
