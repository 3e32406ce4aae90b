"""Benchmark: the full diagnosis (``fitting.diagnose``) on 6-curve datasets.

Target (issue 4): a full diagnose on 6 curves, with the five candidates and up to two
additions (score tests plus refits), in at most 90 s warm on the project's 2-core CPU.

For each dataset it times one cold run (compilation included) and ``--repeats`` warm runs
in the same process, and, as the baseline in the same process, a warm plain fit of the
bending law with the same compiled model (all candidates held at their null values). It
prints medians, the ratio of the diagnosis to that fit, the number of fits and residual-and-
Jacobian evaluations, and writes ``experiments/results/bench_diagnose.txt``.

    python -m experiments.bench_diagnose            # demo data (6 x 14) and shared (6 x 25)
    python -m experiments.bench_diagnose --repeats 1 --only demo
"""

import argparse
import os
import statistics
import time
from pathlib import Path

import fitting as ft
from fitting._diagnose.score import parameter_names

ROOT = Path(__file__).resolve().parents[1]
DATASETS = {
    "demo": ROOT / "jaxtube" / "data" / "demo_hidden_effect.csv",
    "shared": ROOT / "tests" / "data" / "cantilever_shear.csv",
}


def _evaluations(diagnosis) -> tuple[int, int]:
    fits = [diagnosis.baseline] + [row.fit for step in diagnosis.steps for row in step.candidates]
    fits += [row.fit for row in diagnosis.final_candidates]
    return len(fits), sum(f.convergence.evaluations for f in fits)


def bench(name: str, repeats: int) -> list[str]:
    data = ft.load_measurements(DATASETS[name])
    options = ft.DiagnoseOptions(progress=False)
    t0 = time.perf_counter()
    diagnosis = ft.diagnose(data, options=options)
    cold = time.perf_counter() - t0
    warm = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        diagnosis = ft.diagnose(data, options=options)
        warm.append(time.perf_counter() - t0)
    # Baseline in the same process: the plain fit on the same compiled model.
    candidates = ft.default_candidates(ft.PivotScaling())
    held = {n: p.null for c in candidates for n, p in zip(parameter_names(c), c.parameters)}
    fit_times = []
    for _ in range(max(repeats, 1)):
        t0 = time.perf_counter()
        ft.fit(data, effects=candidates, options=ft.FitOptions(
            fixed=held, noise_N=diagnosis.noise, chi2_tol=options.chi2_tol,
            max_iterations=options.baseline_iterations, progress=False))
        fit_times.append(time.perf_counter() - t0)
    fits, evaluations = _evaluations(diagnosis)
    median = statistics.median(warm) if warm else float("nan")
    fit_median = statistics.median(fit_times)
    verdict = ", ".join(diagnosis.verdict) or "nothing"
    shape = f"{len(data)} x {max(c.point_count for c in data)}"
    return [
        f"{name} ({shape} points, {DATASETS[name].name}): verdict {verdict}; "
        f"RMSE {diagnosis.baseline.rmse:.3g} -> {diagnosis.final.rmse:.3g} N "
        f"(noise {diagnosis.noise:.3g} N)",
        f"  diagnose warm: median {median:.1f} s over {len(warm)} runs "
        f"({', '.join(f'{t:.1f}' for t in warm)}); cold (with compilation) {cold:.1f} s",
        f"  {fits} fits, {evaluations} residual-and-Jacobian evaluations "
        f"({median / max(evaluations, 1) * 1e3:.0f} ms each)",
        f"  baseline in the same process: plain fit (warm) {fit_median:.1f} s; "
        f"diagnose / fit = {median / fit_median:.1f}x",
        f"  target <= 90 s warm: {'met' if median <= 90 else 'MISSED'}",
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--only", choices=sorted(DATASETS), default=None)
    args = parser.parse_args()
    lines = [f"bench_diagnose.py, {time.strftime('%Y-%m-%d %H:%M')}, {os.cpu_count()} CPUs, "
             f"load average {os.getloadavg()[0]:.2f} at start"]
    for name in ([args.only] if args.only else list(DATASETS)):
        lines += bench(name, args.repeats)
        print("\n".join(lines[-5:]), flush=True)
    lines.append(f"load average {os.getloadavg()[0]:.2f} at the end")
    out = ROOT / "experiments" / "results" / "bench_diagnose.txt"
    out.write_text("\n".join(lines) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
