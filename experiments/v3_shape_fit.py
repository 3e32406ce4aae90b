"""One V3 calibration fit, timed warm: five of the values the diagnosis ends with (the bending
law's factor, the front bridle's and the trailing edge's rest lengths, the torsion law's
factor, the struts' bending; ``--values``) fitted to the five 0.15 bar cases from the plain
model (Breukels' 2011 law unscaled, the model file's line lengths), every solve from the
case's last equilibrium (:class:`fitting.CaseSolver` ``warm_starts=True``, the default);
``--cold``: the same fit again with every solve by the case's route from the model file's
shape, in the same process. The programs are compiled ahead by two solves of every case (the
route, then the warm start), so every second counted is warm.

Prints and writes ``experiments/results/v3_shape_fit.txt``: per fit its wall time,
evaluations, values and per case the Newton iterations and seconds per solve.

Usage: ``python -m experiments.v3_shape_fit [--steps 12] [--cold]``
"""

import argparse
import statistics
import time
from pathlib import Path

import fitting
import jaxtube as jt

ROOT = Path(__file__).resolve().parent
CASES = ["P1_S", "P1_PL1", "P1_PL2", "P1_TL1", "P1_TL2"]
VALUES = ("bending_scale", "rest_length_factors.front_bridle",
          "rest_length_factors.trailing_edge", "torsion_scale", "bending_class_factors.struts")


def fit(campaign, values, warm: bool, steps: int) -> tuple:
    """``(calibration, solver, wall seconds)`` of one fit."""
    solver = fitting.CaseSolver(campaign, tangent_values=values, warm_starts=warm)
    for case in CASES:  # compile ahead, the route and the warm start (a new solver below:
        for _ in range(2):  # no start is kept)
            solver.tangents(campaign.case(case), campaign.model, values)
    solver = fitting.CaseSolver(campaign, tangent_values=values, warm_starts=warm)
    started = time.perf_counter()
    found = fitting.calibrate_campaign(campaign, campaign.model, values, CASES, solver,
                                       max_steps=steps)
    return found, solver, time.perf_counter() - started


def summary(name, found, solver, seconds) -> str:
    lines = [f"{name}: {seconds:.1f} s wall, {found.evaluations} evaluations, "
             + ", ".join(f"{n} {v:.4f} +- {e:.4f}" for n, v, e in
                         zip(found.names, found.values, found.standard_errors))
             + f"; converged {found.converged} ({found.message})"]
    for case in CASES:
        solves = [r for r in solver.record if r["case"] == case]
        lines.append(f"  {case}: {len(solves)} solves ({sum(r['warm'] for r in solves)} "
                     f"warm), Newton iterations median "
                     f"{statistics.median(r['newton_iterations'] for r in solves):.0f}, "
                     f"total {sum(r['newton_iterations'] for r in solves)}; seconds median "
                     f"{statistics.median(r['seconds'] for r in solves):.2f}, total "
                     f"{sum(r['seconds'] for r in solves):.1f}"
                     + "".join(f"; {r['result']} ({'warm' if r['warm'] else 'route'}, "
                               f"{r['newton_iterations']} steps)"
                               for r in solves if not r["converged"]))
    lines.append("  smooth RMS [mm]: " + ", ".join(
        f"{c} {found.rms_mm_before[c]:.1f} -> {found.rms_mm_after[c]:.1f}" for c in CASES))
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=12, help="Gauss-Newton steps per fit")
    parser.add_argument("--values", nargs="+", default=VALUES)
    parser.add_argument("--cold", action="store_true",
                        help="also fit with every solve from the model file's shape")
    args = parser.parse_args()
    jt.enable_compilation_cache()
    campaign = fitting.read_campaign(ROOT / "data" / "v3_hanging" / "campaign.toml")
    report = []
    runs = (("warm starts", True),) + ((("from the model file's shape", False),)
                                       if args.cold else ())
    for name, warm in runs:
        text = summary(name, *fit(campaign, tuple(args.values), warm, args.steps))
        print(text, flush=True)
        report.append(text)
    out = ROOT / "results" / "v3_shape_fit.txt"
    out.write_text("\n".join(report) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
