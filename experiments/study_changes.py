"""What a change of the diagnosis' rule did to the diagnosis study: the stored records
(``experiments/results/diagnosis_study/designs/``) against the same designs' records at an
earlier commit, design by design, and the issue's targets from each (docs/diagnosis-study.md,
"The baseline's basin").

    python -m experiments.study_changes --before a50ec1c --designs 85

Per design whose physical verdict or final RMSE changed: the hidden effect, what was named
and the final RMSE over the noise floor before and after, and what restarting the baseline
did (``baseline_restart`` of the record: the restart kept, the chi^2 it gained). A design
whose baseline was not restarted must be unchanged (the rule leaves its path alone): the
script says whether it is.
"""

from __future__ import annotations

import argparse
import json
import subprocess

import fitting as ft
from experiments.diagnosis_study import RESULTS

#: Final RMSE ratios within this relative difference count as unchanged (the fits' stopping
#: points are deterministic; this only absorbs rounding in the records).
SAME = 1e-6


def records_at(revision: str, designs) -> dict[str, dict]:
    """The records of ``designs`` stored at git ``revision`` (by design name)."""
    out = {}
    for design in designs:
        path = (RESULTS / "designs" / f"{design.name}.json").relative_to(
            RESULTS.parents[2])
        shown = subprocess.run(["git", "show", f"{revision}:{path}"], capture_output=True,
                               text=True, cwd=RESULTS.parents[2])
        if shown.returncode == 0:
            out[design.name] = json.loads(shown.stdout)
    return out


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
    parser.add_argument("--before", default="a50ec1c", help="git revision of the old records")
    parser.add_argument("--designs", type=int, default=85, help="first N designs (default 85)")
    parser.add_argument("--seed", type=int, default=0, help="study seed (default 0)")
    args = parser.parse_args(argv)
    designs = [ft.draw_study_design(i, args.seed) for i in range(args.designs)]
    before = records_at(args.before, designs)
    after = {d.name: r for d in designs
             if (r := ft.stored_study_record(RESULTS / "designs" / f"{d.name}.json", d))}
    both = [name for name in after if name in before and after[name].get("error") is None
            and before[name].get("error") is None]
    print(f"{len(both)} designs diagnosed before ({args.before}) and now")
    print(f"  {'design':<15}{'hidden':<30}{'before':>22}{'now':>22}  baseline restart")
    changed = better = worse = 0
    unrestarted, unrestarted_same = 0, 0
    for name in both:
        old, new = before[name], after[name]
        restart = new.get("baseline_restart")
        same = (old["found"] == new["found"]
                and abs(_ratio(new) / _ratio(old) - 1.0) <= SAME)
        if not restart:
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
              f"{old['found'] + f', {_ratio(old):.2f}x':>22}"
              f"{new['found'] + f', {_ratio(new):.2f}x':>22}  {words}")
    restarted = [after[n]["baseline_restart"] for n in both if after[n].get("baseline_restart")]
    print(f"changed: {changed} (final RMSE lower in {better}, higher in {worse}); baseline "
          f"restarted in {len(restarted)} of {len(both)} (a restart kept in "
          f"{sum(r['kept'] > 0 for r in restarted)}); not restarted and unchanged: "
          f"{unrestarted_same} of {unrestarted}")
    print(f"before: {_targets([before[n] for n in both])}")
    print(f"now:    {_targets([after[n] for n in both])}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
