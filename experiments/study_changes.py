"""What a change of the diagnosis' rule did to the diagnosis study: the records of a run with
the change (``--after``, e.g. ``experiments/results/diagnosis_study/baseline_restart/``)
against the same designs' records of the rule as it is (``--before``, the study's
``experiments/results/diagnosis_study/``), design by design, and the issue's targets from
each (docs/diagnosis-study.md, "The baseline's basin" and fix 6 of "Why the final model
missed the noise floor").

    python -m experiments.study_changes --designs 85 \
        --before experiments/results/diagnosis_study/one_refit_start
    python -m experiments.study_changes --designs 130 \
        --before experiments/results/diagnosis_study/one_refit_start \
        --after experiments/results/diagnosis_study

Per design whose physical verdict or final RMSE changed: the hidden effect, what was named
and the final RMSE over the noise floor before and after, and what restarting the baseline
did (``baseline_restart`` of the record: the restart kept, the chi^2 it gained). A design
whose baseline was not restarted, or kept its first fit, must be unchanged (the rule leaves
its path alone): the script says whether it is.

``--beyond-collapse`` scores a narrower rule from the same records: restart only where the
first fit leaves a coordinate of a pivot other than the last (the collapse pivot, which
curves stopping short of collapse do not determine) on its box; every other design keeps
its ``--before`` record (its path is the rule as it is).
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path
from statistics import median

import fitting as ft
from experiments.diagnosis_study import RESULTS
from fitting._bench.scaling import PivotScaling

#: Final RMSE ratios within this relative difference count as unchanged (the fits' stopping
#: points are deterministic; this only absorbs rounding in the records).
SAME = 1e-6


def records_in(folder: Path, designs) -> dict[str, dict]:
    """The records of ``designs`` stored under ``folder/designs`` (by design name)."""
    return {d.name: r for d in designs
            if (r := ft.stored_study_record(folder / "designs" / f"{d.name}.json", d))}


def beyond_collapse(record: dict) -> bool:
    """Whether the record's baseline restart was for a coordinate of a pivot below the last
    of the paper-form law (``kappa[3]``, ``M[3]`` with pivots (1,1,1)) on its box."""
    last = sum(PivotScaling().pivots_per_regime)
    return any(not name.split(".")[0].endswith(f"[{last}]")
               for name in record["baseline_restart"]["on_bounds"])


def _ratio(record: dict) -> float:
    return record["final_rmse_N"] / record["noise_floor_N"]


def _targets(records) -> str:
    summary = ft.study_summary(records)
    rates = (summary["false_alarm"]["rate"], summary["power_resolvable"]["found_clean"],
             summary["final_rmse_over_floor"]["within"])
    alarm, power, within = ("n/a" if r is None else f"{r:.0%}" for r in rates)
    median = summary["final_rmse_over_floor"].get("q50", float("nan"))
    return (f"false alarms {alarm} of {summary['false_alarm']['nulls']}; SNR > 3 separable "
            f"found alone {power} of {summary['power_resolvable']['effects']}; final within "
            f"1.3x the floor {within} (median {median:.2f}x)")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", type=Path, default=RESULTS,
                        help=f"results of the rule as it is (default {RESULTS})")
    parser.add_argument("--after", type=Path, default=RESULTS / "baseline_restart",
                        help="results with the change (default BEFORE/baseline_restart)")
    parser.add_argument("--designs", type=int, default=85, help="first N designs (default 85)")
    parser.add_argument("--seed", type=int, default=0, help="study seed (default 0)")
    parser.add_argument("--beyond-collapse", action="store_true",
                        help="score the narrower rule (module docstring)")
    args = parser.parse_args(argv)
    designs = [ft.draw_study_design(i, args.seed) for i in range(args.designs)]
    before, after = records_in(args.before, designs), records_in(args.after, designs)
    if args.beyond_collapse:
        after = {name: (record if record.get("baseline_restart") and beyond_collapse(record)
                        else before.get(name, record)) for name, record in after.items()}
    both = [name for name in after if name in before and after[name].get("error") is None
            and before[name].get("error") is None]
    print(f"{len(both)} designs diagnosed by both rules")
    print(f"  {'design':<15}{'hidden':<30}{'before':>30}{'after':>30}  baseline restart")
    changed = better = worse = 0
    unrestarted, unrestarted_same = 0, 0
    for name in both:
        old, new = before[name], after[name]
        restart = new.get("baseline_restart")
        same = (old["found"] == new["found"]
                and abs(_ratio(new) / _ratio(old) - 1.0) <= SAME)
        if not restart or restart["kept"] == 0:
            unrestarted += 1
            unrestarted_same += same
        if same:
            continue
        changed += 1
        better += _ratio(new) < _ratio(old)
        worse += _ratio(new) > _ratio(old)
        words = ("not restarted" if not restart else
                 "first fit kept" if restart["kept"] == 0 else
                 f"restart {restart['kept']} kept, chi^2 -{restart['chi2_gain']:.4g}")
        print(f"  {name:<15}{new['hidden']:<30}"
              f"{old['found'] + f', {_ratio(old):.2f}x':>30}"
              f"{new['found'] + f', {_ratio(new):.2f}x':>30}  {words}")
    restarted = [after[n]["baseline_restart"] for n in both if after[n].get("baseline_restart")]
    print(f"changed: {changed} (final RMSE lower in {better}, higher in {worse}); baseline "
          f"restarted in {len(restarted)} of {len(both)} (a restart kept in "
          f"{sum(r['kept'] > 0 for r in restarted)}); baseline as before (not restarted, or "
          "first fit kept) and outcome unchanged: "
          f"{unrestarted_same} of {unrestarted}")
    if restarted:
        counts = Counter(name for r in restarted for name in r["on_bounds"])
        seconds = [r["seconds"] for r in restarted]
        print("first fits' coordinates on their box: " + ", ".join(
            f"{name} {count}" for name, count in counts.most_common())
              + f"; restarts' seconds median {median(seconds):.0f}, largest {max(seconds):.0f}")
    print(f"before: {_targets([before[n] for n in both])}")
    print(f"after:  {_targets([after[n] for n in both])}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
