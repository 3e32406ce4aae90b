"""The diagnosis study of issue 34: random designs from the independent continuum solver
(hidden effect none / one / two, sizes from barely detectable to large, random setups and
noise), each diagnosed by :func:`fitting.diagnose`; then the confusion table, the
false-alarm rate on nulls, power against the effect's signal-to-noise ratio, the "cannot
be told apart" statements against what each design can separate, the noise estimate's
error, the final RMSE against the noise floor and seconds per diagnosis, against the
issue's targets (designs and rules: :mod:`fitting._study`).

Designs run on Dask ``distributed`` (``pip install .[study]``): a local cluster of
``--workers`` processes, or ``--scheduler ADDRESS`` for a running cluster. Each design's
record is written to ``RESULTS/designs/<name>.json`` as it ends; a second run with the same
``--seed`` does not run stored designs again (stop it any time and start it again). Then
``RESULTS/summary.json``, ``RESULTS/report.txt`` and ``RESULTS/diagnosis_study.png`` are
written from every stored record of the drawn designs.

    python -m experiments.diagnosis_study --quick                # a dozen small designs
    python -m experiments.diagnosis_study --designs 300 --workers 2
    python -m experiments.diagnosis_study --designs 300 --report-only   # tables only
    python -m experiments.diagnosis_study --designs 300 --noise-only    # the noise estimate
    python -m experiments.diagnosis_study --designs 85 --baseline-starts 4 \
        --results experiments/results/diagnosis_study/baseline_restart  # the restart measured
    python -m experiments.diagnosis_study --designs 85 --noise-order 3 \
        --results experiments/results/diagnosis_study/noise_order_3  # the estimator's order

``--noise-only`` makes each design's data and compares the model-free noise estimate of
difference orders 1, 2 (the default) and 3 with the noise floor, without a diagnosis
(``RESULTS/noise/``, ``RESULTS/noise_report.txt``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import fitting as ft
import jaxtube as jt

RESULTS = Path(__file__).resolve().parent / "results" / "diagnosis_study"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="a dozen small designs (3-4 curves of 8 points)")
    parser.add_argument("--designs", type=int, default=300, help="designs to draw (default 300)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the designs (default 0)")
    parser.add_argument("--workers", type=int, default=1,
                        help="local cluster's worker processes (default 1)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="a running Dask scheduler (e.g. tcp://host:8786) instead of a "
                             "local cluster")
    parser.add_argument("--results", type=Path, default=None,
                        help=f"output directory (default {RESULTS}, _quick for --quick)")
    parser.add_argument("--noise-only", action="store_true",
                        help="only the noise estimate against the floor (no diagnosis)")
    parser.add_argument("--baseline-starts", type=int,
                        default=ft.DiagnoseOptions.baseline_starts,
                        help="DiagnoseOptions.baseline_starts: starts of the baseline when its "
                             "first fit ends on its box (default "
                             f"{ft.DiagnoseOptions.baseline_starts}: no restart)")
    parser.add_argument("--noise-order", type=int, default=ft.DiagnoseOptions.noise_order,
                        help="DiagnoseOptions.noise_order: the model-free noise estimate's "
                             f"difference order (default {ft.DiagnoseOptions.noise_order})")
    parser.add_argument("--report-only", action="store_true",
                        help="write the tables (and figure) from the stored records, run "
                             "nothing")
    args = parser.parse_args(argv)
    count = 12 if args.quick else args.designs
    results = args.results or (RESULTS.with_name(RESULTS.name + "_quick") if args.quick
                               else RESULTS)
    designs = [ft.draw_study_design(k, args.seed, small=args.quick) for k in range(count)]
    if args.noise_only:
        return noise_only(designs, results, args)
    if args.report_only:
        records = stored(designs, results / "designs")
    else:
        with ft.open_cluster_client(args.scheduler, args.workers) as client:
            client.run(jt.enable_compilation_cache)
            records, ran = ft.run_study(designs, results / "designs", client,
                                        baseline_starts=args.baseline_starts,
                                        noise_order=args.noise_order)
        print(f"ran {ran} designs; {count - ran} were stored already", file=sys.stderr)
    summary = ft.study_summary(records)
    summary["seed"], summary["drawn"] = args.seed, count
    report = (f"diagnosis study: {len(records)} of {count} drawn designs (seed {args.seed})\n"
              + ft.study_report(summary))
    ft.write_json(results / "summary.json", summary)
    (results / "report.txt").write_text(report + "\n")
    ft.study_figure(records).savefig(results / "diagnosis_study.png", dpi=110)
    print(report)
    return 0


def stored(designs, folder: Path) -> list[dict]:
    """The records stored in ``folder`` of the drawn ``designs`` (the others are left out)."""
    return [r for d in designs
            if (r := ft.stored_study_record(folder / f"{d.name}.json", d)) is not None]


def noise_only(designs, results: Path, args) -> int:
    """The noise estimate of each design against its floor (module docstring)."""
    if args.report_only:
        records = stored(designs, results / "noise")
    else:
        with ft.open_cluster_client(args.scheduler, args.workers) as client:
            records, _ = ft.run_study(designs, results / "noise", client,
                                      task=ft.noise_estimate_errors)
    summary = ft.noise_summary(records)
    lines = [f"noise estimate / noise floor - 1 over {len(records)} of {len(designs)} drawn "
             f"designs (seed {args.seed})",
             f"  {'order':<8}{'designs':>8}{'within 25 %':>13}{'supported':>11}"
             f"{'within there':>14}  quantiles 5/25/50/75/95 %"]
    for order, row in summary.items():
        quantiles = " ".join(f"{row[k]:+.2f}" for k in row if k.startswith("q"))
        within, there = ("n/a" if row[k] is None else f"{row[k]:.0%}"
                         for k in ("within", "within_supported"))
        lines.append(f"  {order:<8}{row['designs']:>8}{within:>13}{row['supported']:>11}"
                     f"{there:>14}  {quantiles}")
    lines.append("  supported: designs whose sampling ceiling (white noise at their own "
                 "deflections) is within 25 % in >= 95 % of draws")
    ft.write_json(results / "noise_summary.json", summary)
    (results / "noise_report.txt").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
