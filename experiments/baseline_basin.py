"""Which diagnosis-study designs' baselines end on their box: the baseline's first fit (from
the physics guess, as :func:`fitting.diagnose` starts it, with its options and candidates
held at their null), per design, with the free coordinates it leaves on their box bounds
(:func:`fitting._diagnose.restart.on_box_bounds`). Those designs, and only those, are
restarted by the diagnosis (``DiagnoseOptions.baseline_starts``); every other design's
diagnosis runs exactly as before (docs/diagnosis-study.md, "The baseline's basin").

One JSON row per design is stored as it ends (a second run skips stored rows):

    python -m experiments.baseline_basin --designs 85
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import time
from pathlib import Path

from tqdm.auto import tqdm

from experiments._study_design import design_setup
from fitting import DiagnoseOptions
from fitting._bench.rig import DEFAULT_SEGMENTS, CantileverRig
from fitting._bench.scaling import PivotScaling
from fitting._calibrate.fit import fit_problem
from fitting._calibrate.problem import make_problem
from fitting._diagnose.restart import on_box_bounds
from fitting._diagnose.score import chi2
from fitting._json import write_json

RESULTS = Path("experiments/results/diagnosis_study/baseline_basin.json")


def first_fit(index: int, seed: int) -> dict:
    """Design ``index`` of ``seed``: the baseline's first fit, its chi^2 (noise units), RMSE
    over the noise floor and the coordinates it leaves on their box bounds."""
    with contextlib.redirect_stdout(io.StringIO()):  # design_setup prints the design's line
        setup = design_setup(index, seed, DiagnoseOptions().baseline_iterations)
    problem = make_problem(setup.data, PivotScaling(), CantileverRig(segments=DEFAULT_SEGMENTS),
                           setup.fit_options, effects=setup.candidates)
    started = time.perf_counter()
    result = fit_problem(problem, setup.fit_options)
    return {"name": setup.design.name, "hidden": setup.design.hidden_label,
            "on_bounds": on_box_bounds(result), "chi2": chi2(result),
            "rmse_over_floor": result.rmse / setup.noise_floor_N,
            "converged": result.convergence.converged,
            "seconds": time.perf_counter() - started}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--designs", type=int, default=85, help="first N designs (default 85)")
    parser.add_argument("--seed", type=int, default=0, help="study seed (default 0)")
    parser.add_argument("--out", type=Path, default=RESULTS, help=f"rows (default {RESULTS})")
    args = parser.parse_args(argv)
    rows = json.loads(args.out.read_text()) if args.out.exists() else {}
    for index in tqdm(range(args.designs), desc="baseline first fits", unit="design"):
        key = f"{args.seed}/{index}"
        if key not in rows:
            rows[key] = first_fit(index, args.seed)
            write_json(args.out, rows)
    on_box = [row for row in rows.values() if row["on_bounds"]]
    print(f"{len(on_box)} of {len(rows)} baselines end with coordinates on their box bounds:")
    for row in on_box:
        print(f"  {row['name']} ({row['hidden']}): {row['rmse_over_floor']:.2f}x the floor, "
              f"{', '.join(row['on_bounds'])}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
