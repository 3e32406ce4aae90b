"""Where the test suite's time goes: one fit evaluation split into its solves and tangents,
and one solver program's compile time under XLA's compile options.

Two measurements behind the README's "How long it takes, and why" (section "Two commands"):

1. **A fit evaluation** on a 6 x 14 hidden-effect design (``tests/data/effects/
   tf_clamp_compliance.csv``, the plain paper scaling, 12 coordinates): the compiled
   residual-and-Jacobian function the fit calls (``fitting._calibrate.problem``) against the
   residuals alone (the primal equilibrium solves, no tangents), warm medians, and the
   Newton iterations the solves took.
2. **A solver program's compilation**: the chain case of ``tests/test_sparse_kkt.py``
   (solve and reverse-mode gradient, dense route): its size in StableHLO lines, the source
   lines that contribute most operations, and the compile time with XLA options that might
   cut it (``compiler_options`` of ``jax.stages.Lowered.compile``), each with the compiled
   program's warm run time.

This is a script, not a test. Run from the repository root::

    python -m experiments.profile_suite_costs [--out FILE]

It prints and writes ``experiments/results/profile_suite_costs.txt``.
"""

from __future__ import annotations

import argparse
import collections
import os
import re
import time
from pathlib import Path

os.environ.setdefault("JAXTUBE_NO_COMPILATION_CACHE", "1")

import jax
import jax.numpy as jnp
import numpy as np

import jaxtube  # noqa: F401  (float64, threads)
from fitting._calibrate import problem as calibration
from fitting._data.load import load_measurements

ROOT = Path(__file__).resolve().parents[1]

jax.config.update("jax_numpy_dtype_promotion", "strict")

DESIGN = ROOT / "tests" / "data" / "effects" / "tf_clamp_compliance.csv"
OPTIONS = ({}, {"xla_backend_optimization_level": 0},
           {"xla_llvm_disable_expensive_passes": True},
           {"xla_cpu_use_fusion_emitters": False})


def _median_seconds(fn, repeats: int = 5) -> float:
    jax.block_until_ready(fn())
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn())
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def fit_evaluation(say) -> None:
    problem = calibration.make_problem(load_measurements(DESIGN))
    static, args = problem.static(), problem.residual_args()
    vector = jnp.asarray(problem.full(problem.base[np.asarray(problem.free_index)]))
    primal = jax.jit(lambda v, *a: calibration._residual_fn(v, *a, **static)[0])
    both = _median_seconds(lambda: calibration._residuals_and_jacobian(vector, *args,
                                                                       **static))
    alone = _median_seconds(lambda: primal(vector, *args))
    prediction = calibration._residuals_and_jacobian(vector, *args, **static)[2]
    iterations = np.asarray(prediction.iterations)
    say(f"fit evaluation, {DESIGN.name}: data {problem.batch.force.shape}, "
        f"{vector.shape[0]} coordinates")
    say(f"  residuals and Jacobian {both * 1e3:.0f} ms, residuals alone (the primal solves) "
        f"{alone * 1e3:.0f} ms, warm medians of 5")
    say(f"  Newton iterations: {int(iterations.sum())} over {iterations.size} points "
        f"({iterations.mean():.2f} per point)")


def _operations_by_source_line(text: str) -> collections.Counter:
    """StableHLO operations per jaxtube source line (locations resolved through their
    chains of ``#loc`` references)."""
    definitions = dict(re.findall(r"^#(loc\d+) = loc\((.*)\)$", text, re.M))

    def resolve(ref, depth=0):
        s = definitions.get(ref, ref)
        if depth < 30:
            s = re.sub(r"#(loc\d+)", lambda m: resolve(m.group(1), depth + 1), s)
        return s

    counts = collections.Counter()
    for line in text.split("\n"):
        if "stablehlo." not in line:
            continue
        found = re.search(r"loc\(#(loc\d+)\)", line)
        if not found:
            continue
        frames = re.findall(r'"[^"]*?(jaxtube/[^"]+)":(\d+)', resolve(found.group(1)))
        if frames:
            counts[f"{frames[0][0]}:{frames[0][1]}"] += 1
    return counts


def solver_compilation(say) -> None:
    from tests.test_sparse_kkt import CASES, _solve_and_gradient

    name, (structure, params), control = CASES[0]
    lowered = jax.jit(lambda p: _solve_and_gradient(structure, p, control, "dense")).lower(
        params)
    text = lowered.as_text(debug_info=True)
    counts = _operations_by_source_line(text)
    rotation = sum(v for k, v in counts.items() if k.startswith("jaxtube/_rotation.py"))
    say(f"solver program: {name} case of tests/test_sparse_kkt.py, dense route, solve and "
        f"gradient: {text.count(chr(10))} lines of StableHLO (with locations), "
        f"{sum(counts.values())} operations traced to jaxtube lines, {rotation} of them "
        "to jaxtube/_rotation.py")
    for where, count in counts.most_common(8):
        say(f"  {count:5d}  {where}")
    for options in OPTIONS:
        start = time.perf_counter()
        compiled = lowered.compile(compiler_options=options)
        seconds = time.perf_counter() - start
        run = _median_seconds(lambda: compiled(params), repeats=3)
        say(f"  compile {seconds:5.1f} s, warm run {run * 1e3:6.1f} ms  options {options}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default=str(ROOT / "experiments" / "results"
                                             / "profile_suite_costs.txt"))
    args = parser.parse_args()
    lines = []

    def say(text):
        print(text, flush=True)
        lines.append(text)

    say(f"load average {' / '.join(f'{x:.2f}' for x in os.getloadavg())} (2 CPUs); "
        f"jax {jax.__version__}")
    fit_evaluation(say)
    solver_compilation(say)
    Path(args.out).write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
