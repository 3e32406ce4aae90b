"""``jaxtube diagnose`` and ``jaxtube demo`` (registered by :mod:`fitting._cli.main`).

``jaxtube diagnose DATA.csv --out DIR [--effect NAME|FILE.py:Class ...]``: the whole loop of
:func:`fitting.diagnose` (baseline fit with the paper scaling, the comparison and where it
fails, the ranking of the candidates, the additions step by step) on a measurement file
(format in :mod:`fitting._data`). Prints the before/after table and the verdict, and writes
into DIR:

- ``diagnosis.json``: noise, baseline, steps (each with ``added``, ``rmse_N`` and the ranked
  ``candidates``: ``effect``, ``rmse_N``, ``delta_bic``, ``score_statistic``, ...), verdict,
  statements and the final model (format ``jaxtube-diagnosis``, version 1);
- ``report.txt``: what the terminal shows;
- ``fit_0_baseline.png``, ``fit_1_<effect>.png``, ...: measured against model, with bands and
  residuals, at each step;
- ``where_it_fails.png`` (baseline) and ``where_it_fails_final.png``: residuals by curve,
  pressure, radius, length, regime and wrinkled extent;
- ``ranking.png`` (BIC drop and score of every candidate at every step) and
  ``before_after.png`` (error per curve, baseline and after each addition);
- ``parameters.json``: the final model's law, as ``jaxtube fit`` writes it.

``jaxtube demo [--out DIR]``: the same on the bundled dataset
``jaxtube/data/demo_hidden_effect.csv`` (a hidden effect, made by the independent continuum
solver; see ``jaxtube/data/README.md``), then says what was hidden.

No result is lost: each output is built and written on its own, so one that fails (a figure,
say) is named on stderr and under ``output_failures`` in ``diagnosis.json`` (written last)
while the others are written; numbers that are undefined (a cross-validation without a valid
fold design) are ``null`` in the JSON.

Exit codes: 0 a verdict was reached with a converged final model (a baseline that did not
converge, expected when it misses an effect, is reported in ``report.txt`` and the JSON, not
here); 1 the final model did not converge, or ``diagnosis.json`` could not be written
(whatever could be written is); 2 bad input (nothing written).
"""

from __future__ import annotations

import sys
import time
from importlib import resources
from pathlib import Path

from .._bench.effects import resolve_effect
from .._bench.rig import DEFAULT_SEGMENTS, CantileverRig
from .._bench.scaling import PivotScaling
from .._calibrate.problem import FitError
from .._diagnose.diagnosis import diagnose
from .._diagnose.ranking import DiagnoseOptions, default_candidates
from .._diagnose.report import diagnosis_report
from .._figures.plots import before_after_figure, fit_figure, ranking_figure, where_it_fails_figure
from .._json import write_json
from .common import (
    add_data_argument,
    add_model_size_arguments,
    load_input,
    positive_float,
    positive_int,
    write_directory,
)

DEMO_DATA = "demo_hidden_effect.csv"
#: What the bundled demo dataset hides (jaxtube/data/README.md); printed after the verdict.
DEMO_TRUTH = ("clamp_compliance", "the rig's clamp is a rotational spring of 1500 N m/rad, not "
                                  "rigid")


def add_diagnose(subparsers) -> None:
    parser = subparsers.add_parser(
        "diagnose", help="find which physical effect the model lacks, add it, refit",
        description="Fit the bending law, compare with the measurements, rank candidate "
                    "effects (score tests, refits, BIC, cross-validation), add the "
                    "significant ones one at a time and report before/after.")
    add_data_argument(parser)
    _add_common(parser, default_out=None)
    parser.set_defaults(run=run_diagnose)


def add_demo(subparsers) -> None:
    parser = subparsers.add_parser(
        "demo", help="run the diagnosis on the bundled dataset with a hidden effect",
        description="The whole diagnosis on jaxtube/data/demo_hidden_effect.csv (made by the "
                    "independent continuum solver with a hidden effect).")
    _add_common(parser, default_out=Path("out/demo"))
    parser.set_defaults(run=run_demo, data=None)


def _add_common(parser, default_out) -> None:
    parser.add_argument("--out", type=Path, required=default_out is None, default=default_out,
                        help="output directory" + (f" (default {default_out})"
                                                   if default_out else ""))
    parser.add_argument("--effect", action="append", default=[], metavar="NAME|FILE.py:Class",
                        help="an extra candidate: a user's Effect subclass (repeatable)")
    parser.add_argument("--candidates", default=None, metavar="NAME,NAME",
                        help="restrict the candidates (default: radius_scaling, "
                             "unwrinkled_linearity, shear, reinforcement, clamp_compliance, "
                             "self_weight, and --effect ones)")
    parser.add_argument("--noise-N", type=positive_float, default=None,
                        help="force noise standard deviation [N] (default: estimated from "
                             "the scatter of the data, without a model)")
    add_model_size_arguments(parser)
    parser.add_argument("--max-additions", type=positive_int, default=3)
    parser.add_argument("--no-refine", action="store_true",
                        help="do not refine the law's pivots when no candidate is significant "
                             "and the residuals are still systematic")
    parser.add_argument("--baseline-starts", type=positive_int, default=1,
                        help="starts of the baseline fit when its first fit ends with law "
                             "coordinates on their box bounds, the first included; the best "
                             "is kept (default 1: no restart; see docs/diagnosis-study.md)")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")


def run_demo(args) -> int:
    args.data = Path(str(resources.files("jaxtube") / "data" / DEMO_DATA))
    print(f"jaxtube demo: diagnosing {args.data}\n  six bench-style cantilever curves made by "
          "the independent continuum shooting solver, with one physical effect hidden in "
          "them; the model starts without any effect.", file=sys.stderr)
    code = run_diagnose(args)
    if code != 2:
        print(f"\nhidden in the demo data: {DEMO_TRUTH[0]} ({DEMO_TRUTH[1]}); "
              f"see jaxtube/data/README.md")
    return code


def run_diagnose(args) -> int:
    started = time.perf_counter()
    data = load_input(args)
    if data is None:
        return 2
    try:
        scaling = PivotScaling(pivots_per_regime=args.pivots)
        user = tuple(resolve_effect(text) for text in args.effect)
        candidates = default_candidates(scaling, user)
        if args.candidates:
            wanted = [name.strip() for name in args.candidates.split(",") if name.strip()]
            known = {c.name: c for c in candidates}
            unknown = [name for name in wanted if name not in known]
            if unknown:
                raise ValueError(f"--candidates: unknown {unknown}; expected names from "
                                 f"{sorted(known)}")
            candidates = tuple(known[name] for name in wanted)
        options = DiagnoseOptions(noise_N=args.noise_N,
                                  max_additions=args.max_additions,
                                  refine_pivots=not args.no_refine,
                                  baseline_starts=args.baseline_starts,
                                  progress=not args.quiet)
        rig = CantileverRig(segments=args.segments or DEFAULT_SEGMENTS)
        print(f"diagnosing {len(data)} curves ({data.point_count} points) from {args.data}; "
              f"candidates: {', '.join(c.name for c in candidates)}; compiling the model "
              "(the first evaluation takes a while) ...", file=sys.stderr, flush=True)
        diagnosis = diagnose(data, scaling=scaling, rig=rig, options=options,
                             candidates=candidates)
    except (ValueError, FitError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    document = diagnosis.to_json()
    document["wall_time_s"] = round(time.perf_counter() - started, 3)
    failures = write_outputs(args.out, diagnosis, document)
    report_path = args.out / "report.txt"
    if report_path.exists():
        print(report_path.read_text(), end="")
    written = sorted(p.name for p in args.out.iterdir()) if args.out.is_dir() else []
    print(f"wrote {', '.join(written) or 'nothing'} to {args.out}")
    if "diagnosis.json" in failures:
        return 1
    return 0 if diagnosis.final.convergence.converged else 1


def write_outputs(out: Path, diagnosis, document: dict) -> dict[str, str]:
    """Build and write every output of a diagnosis into ``out``, each on its own: a writer
    that fails (building its figure or writing its file) leaves no file, is named on stderr,
    and the others go on. ``diagnosis.json`` (``document`` with ``output_failures`` added:
    file name -> error) is written last. Returns those failures (file name -> error)."""
    failures: dict[str, str] = {}

    def isolated(name, write):
        def guarded(path):
            try:
                write(path)
            except Exception as error:  # noqa: BLE001 (named, and the other files go on)
                path.unlink(missing_ok=True)
                failures[name] = f"{type(error).__name__}: {error}"
                print(f"error: could not write {name}: {failures[name]}", file=sys.stderr)
        return guarded

    def write_document(path):
        document["output_failures"] = dict(failures)
        write_json(path, document)

    writers = {name: isolated(name, write) for name, write in _writers(diagnosis).items()}
    writers["diagnosis.json"] = isolated("diagnosis.json", write_document)
    write_directory(out, writers)
    return failures


def _figure_writer(build):
    """A writer that builds the figure (``build()``) and saves it: a figure that fails to
    build fails only its own file."""
    return lambda path: build().savefig(path, dpi=110)


def _writers(diagnosis) -> dict:
    """File name -> writer ``(path) -> None`` of every output but ``diagnosis.json``."""
    models = [("baseline", diagnosis.baseline)] + [(s.added, s.fit) for s in diagnosis.steps]
    writers = {"report.txt": lambda path: path.write_text(diagnosis_report(diagnosis) + "\n"),
               "parameters.json": lambda path: write_json(path, diagnosis.final.to_json())}
    for k, (label, result) in enumerate(models):
        added = " + ".join(["baseline"] + [s.added for s in diagnosis.steps[:k]])
        writers[f"fit_{k}_{label}.png"] = _figure_writer(
            lambda result=result, added=added, k=k: fit_figure(
                result, title=f"step {k}: {added}: RMSE {result.rmse:.3g} N (noise "
                              f"{diagnosis.noise:.3g} N)"))
    writers["where_it_fails.png"] = _figure_writer(lambda: where_it_fails_figure(
        diagnosis.baseline, diagnosis.baseline_comparison, "baseline"))
    if diagnosis.steps:
        writers["where_it_fails_final.png"] = _figure_writer(lambda: where_it_fails_figure(
            diagnosis.final, diagnosis.final_comparison,
            "final (+ " + ", ".join(diagnosis.verdict) + ")"))
    writers["ranking.png"] = _figure_writer(lambda: ranking_figure(diagnosis))
    writers["before_after.png"] = _figure_writer(lambda: before_after_figure(diagnosis))
    return writers
