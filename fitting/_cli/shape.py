"""``jaxtube shape``: a kite against its measured 3-D shapes, from a campaign file.

``jaxtube shape compare CAMPAIGN.toml [--model model.json] [--cases A B ...] [--no-figures]
--out DIR``: every case with markers (or the ``--cases`` named) solved with the campaign's
``[model]`` (or ``--model``) and scored against its markers and measured lengths: ``cases.csv``,
``groups.csv``, ``markers.csv``, ``lengths.csv``, ``comparison.json``, ``rms_per_case.png``,
``<case>_shape.png`` (:mod:`fitting._campaign.report`).

``jaxtube shape predict CAMPAIGN.toml [--model model.json] [--cases A B ...] --out DIR``:
every case (or those named) solved: ``DIR/<case>/positions.csv`` (``node,x_m,y_m,z_m``, every
node of the model file; none when the solve did not converge) and ``DIR/<case>/summary.json``
(``converged``, ``seconds`` warm).

``jaxtube shape calibrate CAMPAIGN.toml --values NAME [NAME ...] [--model model.json]
[--cases A B ...] --out DIR``: the values (``bending_scale``, ``rest_length_factors.SET``)
fitted by gradient to the calibration cases (:mod:`fitting._campaign.calibrate`):
``model.json`` (the model, each value with its standard error, what the cases do not
determine), ``cases.csv`` and ``rms_before_after.png`` (each case's smooth RMS before and
after).

``jaxtube shape diagnose CAMPAIGN.toml [--effect NAME|FILE.py:NAME ...] [--model model.json]
[--cases A B ...] [--held-out linearised|refit] --out DIR``: which candidate effect the model
misses (:mod:`fitting._campaign.diagnose`): the baseline (``[diagnose] baseline``) fitted to
the calibration cases, the candidates (``[diagnose] candidates``, default every built-in
effect, plus ``--effect``) ranked by what they gain on cases left out of the fit (by one
linearised step from the fit to every case, or by refitting), the best added
until none passes: ``report.txt``, ``diagnosis.json``, ``model.json`` (the model it ends
with), ``cases.csv``, ``rms_before_after.png`` (baseline and final) and ``ranking.png``.
Exit 1 when the final model did not converge.

The campaign format: ``docs/spec-format.md`` ("Campaign files"); the workflow:
``docs/shapes.md``. Exit codes: 0 success; 1 written, but a solve did not converge (or, for
``compare``, a registration did not meet its tolerance); 2 bad input (every problem named
with file, key and reason; nothing written).
"""

from __future__ import annotations

import functools
import json
import sys
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

import jaxtube as jt

from .._campaign.calibrate import calibrate_campaign
from .._campaign.diagnose import HELD_OUT, diagnose_campaign
from .._campaign.diagnosis_report import diagnosis_report, ranking_figure
from .._campaign.effects import resolve_shape_effect, shape_effects
from .._campaign.file import read_campaign
from .._campaign.kite import unknown_value_words
from .._campaign.model import CampaignError, read_model_file
from .._campaign.report import (
    compare_cases,
    comparison_writers,
    prediction_writers,
    rms_before_after_figure,
)
from .._campaign.solve import CaseSolver
from .._json import finite_or_none, write_json
from .._shape.files import ShapeFileError
from .._shape.markers import load_markers
from .common import bad_output_directory, write_directory


def add_shape(subparsers) -> None:
    """Register ``shape`` (and its ``compare`` and ``predict``) on argparse subparsers."""
    parser = subparsers.add_parser(
        "shape", help="a kite against measured 3-D shapes (campaign file)",
        description="Solve a campaign's cases and compare them with their markers, or "
                    "predict them.")
    commands = parser.add_subparsers(title="shape commands", metavar="COMMAND")
    for name, help_text, run in (
            ("compare", "solve the cases with markers and score them", run_compare),
            ("predict", "solve every case and write its node positions", run_predict),
            ("calibrate", "fit model values to the calibration cases by gradient",
             run_calibrate),
            ("diagnose", "find which candidate effect the model misses", run_diagnose)):
        command = commands.add_parser(name, help=help_text, description=help_text)
        command.add_argument("campaign", type=Path, help="campaign file (TOML)")
        command.add_argument("--model", type=Path, default=None,
                             help="model.json with the model's values (default: the "
                                  "campaign's [model])")
        command.add_argument("--cases", nargs="+", default=None,
                             help="case names (default: every case"
                                  + {"compare": " with markers)", "predict": ")",
                                     "calibrate": " whose role is calibrate)",
                                     "diagnose": " whose role is calibrate)"}[name])
        if name == "calibrate":
            command.add_argument("--values", nargs="+", required=True,
                                 help="the values to fit: bending_scale, "
                                      "rest_length_factors.SET, stiffness_factors.SET (SET: "
                                      "a line set of the campaign)")
        if name == "diagnose":
            command.add_argument("--effect", action="append", default=[],
                                 metavar="NAME|FILE.py:NAME",
                                 help="another candidate: a built-in effect or a user's "
                                      "ShapeEffect (docs/shapes.md)")
            command.add_argument("--held-out", choices=HELD_OUT, default=HELD_OUT[0],
                                 help="how a case left out of the fit is scored: one "
                                      "linearised step from the fit to every case (default) "
                                      "or a fit to the other cases and a solve")
        if name == "compare":
            command.add_argument("--no-figures", action="store_true",
                                 help="write the tables and JSON only")
        command.add_argument("--out", type=Path, required=True, help="output directory")
        command.set_defaults(run=functools.partial(_read_then, run, name))
    parser.set_defaults(run=lambda args: (parser.print_help(sys.stderr), 2)[1])


def _read_then(run, command: str, args) -> int:
    """Read the campaign (and model) of ``args``, then ``run(args, campaign, model, case
    names)``; exit code 2 after saying why when they do not read (nothing written)."""
    read = _read(args, need_markers=command != "predict",
                 calibration=command in ("calibrate", "diagnose"))
    return 2 if read is None else run(args, *read)


def _read(args, need_markers: bool, calibration: bool = False):
    """``(campaign, model, case names)`` or ``None`` after saying why (exit code 2)."""
    if bad_output_directory(args.out):
        return None
    try:
        campaign = read_campaign(args.campaign)
        model = campaign.model if args.model is None else read_model_file(args.model, campaign)
        default = [c.name for c in campaign.cases
                   if (c.role == "calibrate" if calibration else c.markers or not need_markers)]
        names = default if args.cases is None else list(args.cases)
        for name in names:
            case = campaign.case(name)
            if need_markers:
                if case.markers is None:
                    raise KeyError(f"{campaign.path}: case {name!r} has no markers to "
                                   "compare with")
                load_markers(case.markers)  # every marker file checked before any solve
    except (CampaignError, ShapeFileError) as error:
        print(f"error: {error}", file=sys.stderr)
        return None
    except KeyError as error:
        print(f"error: {error.args[0]}", file=sys.stderr)
        return None
    if not names:
        print(f"error: {args.campaign}: no case to {'compare' if need_markers else 'predict'}",
              file=sys.stderr)
        return None
    return campaign, model, names


def run_compare(args, campaign, model, names) -> int:
    """Run ``shape compare``; returns the exit code."""
    solver = CaseSolver(campaign)
    records = compare_cases(campaign, model, names, solver,
                            log=lambda text: print(text, file=sys.stderr, flush=True))
    write_directory(args.out, comparison_writers(campaign, model, records,
                                                 figures=not args.no_figures))
    print(f"{'case':>10} {'RMS mm':>8} {'undef. mm':>9} {'canopy mm':>9} {'lengths':>8} "
          f"{'warm s':>7} converged")
    for record in records:
        score, solved = record["score"], record["solved"]
        lengths = record["lengths"]
        error = (sum(abs(m - v) / v for v, m, _ in lengths.values()) / len(lengths)
                 if lengths else float("nan"))
        canopy = score.canopy_rms_mm
        print(f"{solved.case.name:>10} {score.rms_mm:8.1f} {record['undeformed'].rms_mm:9.1f} "
              f"{'-' if canopy is None else format(canopy, '.1f'):>9} {100 * error:7.1f}% "
              f"{solved.seconds:7.2f} {solved.converged}")
    print(f"wrote {args.out}")
    failed = [r["solved"].case.name for r in records
              if not (r["solved"].converged and r["score"].registration.converged)]
    if failed:
        print(f"warning: not converged (solve or registration): {', '.join(failed)}",
              file=sys.stderr)
    return 1 if failed else 0


def run_predict(args, campaign, model, names) -> int:
    """Run ``shape predict``; returns the exit code."""
    solver = CaseSolver(campaign)
    failed = []
    for name in names:
        solved = solver.solve(campaign.case(name), model)
        folder = args.out / name
        write_directory(folder, prediction_writers(solved, model, campaign))
        if not solved.converged:
            failed.append(name)
            (folder / "positions.csv").unlink(missing_ok=True)  # never an older run's
        print(f"{name}: converged {solved.converged}, warm {solved.seconds:.3f} s, Newton "
              f"{solved.newton_iterations}; wrote {folder}", flush=True)
    if failed:
        print(f"warning: not converged: {', '.join(failed)} (no positions.csv written)",
              file=sys.stderr)
    return 1 if failed else 0


def run_calibrate(args, campaign, model, names) -> int:
    """Run ``shape calibrate``; returns the exit code."""
    for value in args.values:
        words = unknown_value_words(campaign, value)
        if words is not None:
            print(f"error: --values: {words}", file=sys.stderr)
            return 2
    found = calibrate_campaign(campaign, model, args.values, names, CaseSolver(campaign),
                               log=lambda text: print(text, file=sys.stderr, flush=True))
    rows = "case,rms_mm_before,rms_mm_after\n" + "".join(
        f"{c},{found.rms_mm_before[c]!r},{found.rms_mm_after[c]!r}\n" for c in names)
    write_directory(args.out, {
        "model.json": lambda path: path.write_text(json.dumps(found.to_json(), indent=2)
                                                   + "\n"),
        "cases.csv": lambda path: path.write_text(rows),
        "rms_before_after.png": lambda path: rms_before_after_figure(
            found.rms_mm_before, found.rms_mm_after, path),
    })
    for name, value, error in zip(found.names, found.values, found.standard_errors):
        print(f"{name} = {value:.4g} +- {error:.2g}")
    for statement in found.statements:
        print(f"note: {statement}")
    for case in names:
        print(f"{case}: smooth RMS {found.rms_mm_before[case]:.1f} -> "
              f"{found.rms_mm_after[case]:.1f} mm")
    print(f"wrote {args.out / 'model.json'} (converged {found.converged}: {found.message})")
    return 0 if found.converged else 1


def _diagnosis_inputs(args, campaign):
    """``(baseline values, candidate effects)`` of ``shape diagnose``, or ``None`` after
    saying why (exit code 2)."""
    problems = []
    for value in campaign.diagnose_baseline:
        words = unknown_value_words(campaign, value)
        if words is not None:
            problems.append(jt.Problem(str(campaign.path), words, "diagnose.baseline"))
    names = list(campaign.diagnose_candidates or shape_effects(campaign))
    candidates = []
    for key, name in [("diagnose.candidates", n) for n in names] + \
            [("--effect", n) for n in args.effect]:
        try:
            candidates.append(resolve_shape_effect(name, campaign))
        except ValueError as error:
            problems.append(jt.Problem(str(campaign.path), str(error), key))
    if problems:
        print(f"error: {CampaignError(problems)}", file=sys.stderr)
        return None
    return campaign.diagnose_baseline, candidates


def solve_statistics(record) -> dict:
    """``{"warm" | "from_undeformed": {"solves", "newton_iterations_median",
    "seconds_median", "seconds_total"}}`` of a :class:`fitting.CaseSolver`'s record."""
    statistics = {}
    for key, warm in (("warm", True), ("from_undeformed", False)):
        solves = [r for r in record if r["warm"] == warm]
        statistics[key] = {
            "solves": len(solves),
            "newton_iterations_median": finite_or_none(np.median(
                [r["newton_iterations"] for r in solves]) if solves else float("nan")),
            "seconds_median": finite_or_none(np.median([r["seconds"] for r in solves])
                                             if solves else float("nan")),
            "seconds_total": float(sum(r["seconds"] for r in solves))}
    return statistics


def run_diagnose(args, campaign, model, names) -> int:
    """Run ``shape diagnose``; returns the exit code."""
    inputs = _diagnosis_inputs(args, campaign)
    if inputs is None:
        return 2
    if len(names) < 2:
        print(f"error: {args.campaign}: diagnose leaves one case out and needs at least two "
              f"calibration cases, found {len(names)}", file=sys.stderr)
        return 2
    baseline, candidates = inputs
    values = tuple(dict.fromkeys(tuple(baseline) + tuple(
        v for effect in candidates for v in effect.values)))
    solver = CaseSolver(campaign, tangent_values=values)
    started = time.perf_counter()
    with tqdm(desc="shape diagnose fits", unit="fit", file=sys.stderr) as bar:
        found = diagnose_campaign(campaign, model, baseline, candidates, names, solver,
                                  log=lambda text: bar.write(text, file=sys.stderr),
                                  bar=bar, held_out=args.held_out)
    seconds = time.perf_counter() - started
    document = found.to_json() | {"seconds": seconds, "cases": names,
                                  "solves": solve_statistics(solver.record)}
    before, after = found.baseline.rms_mm_after, found.final.rms_mm_after
    rows = "case,rms_mm_start,rms_mm_baseline,rms_mm_final\n" + "".join(
        f"{c},{found.baseline.rms_mm_before[c]!r},{before[c]!r},{after[c]!r}\n"
        for c in names)
    report = diagnosis_report(found, names, seconds)
    write_directory(args.out, {
        "diagnosis.json": lambda path: write_json(path, document),
        "model.json": lambda path: write_json(path, found.final.to_json()),
        "cases.csv": lambda path: path.write_text(rows),
        "report.txt": lambda path: path.write_text(report),
        "rms_before_after.png": lambda path: rms_before_after_figure(before, after, path),
        "ranking.png": lambda path: ranking_figure(found, path),
    })
    print(report, end="")
    print(f"wrote {args.out}")
    return 0 if found.converged else 1
