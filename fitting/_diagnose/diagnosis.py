"""The diagnosis loop: baseline fit, ranking, additions with a backward / swap step, and the
verdict (rules and sources in :mod:`fitting._diagnose.ranking`).

**Iteration.** Add the significant candidate with the lowest BIC and polish the model; then
the backward / swap step (:func:`fitting._diagnose.selection.backward_step`): each earlier
addition is removed if, given the rest, keeping it is no longer significant (likelihood
ratio and BIC), or swapped for a competitor of its own step that, in its place, lowers the
BIC by more than ``SWAP_BIC``, so that the first good-enough explanation does not shadow
the right one. Then the coordinates held since the baseline (it did not determine them) that
the new model determines are freed again when that lowers the BIC
(:func:`fitting._diagnose.selection.release_held`): an addition can make visible what the
baseline could not see. Re-rank the rest from the new model, and stop when none is
significant (or ``max_additions`` is reached).

**Noise.** One noise for every model: the user's, or the model-free estimate with its
standard error (:func:`fitting.estimate_noise_with_error`); the verdict says whether the
final model's residual scatter agrees with it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

from .._bench.effects import Effect
from .._bench.rig import CantileverRig
from .._bench.scaling import PivotScaling
from .._calibrate.fit import fit_problem
from .._calibrate.noise import NoiseEstimate, estimate_noise_with_error
from .._calibrate.problem import make_problem
from .._calibrate.result import FitResult
from .._data import MeasuredData
from .compare import Comparison, compare
from .ranking import (
    CandidateRanking,
    DiagnoseOptions,
    _fit_options,
    default_candidates,
    rank_candidates,
)
from .refinement import PIVOT_REFINEMENTS, refine_pivots
from .report import diagnosis_report
from .restart import BaselineRestart, restart_on_box
from .score import chi2, parameter_names, point_count
from .selection import (
    backward_step,
    hold_undetermined_where_left,
    release_held,
    settle,
)
from .separation import _effect_values, separation_statements
from .validation import blocked_cross_validation
from .verdict import noise_words, verdict_words


@dataclasses.dataclass(frozen=True)
class DiagnosisStep:
    """One addition: ``added`` (effect name), the ranking that chose it (best first), the
    model after adding it and after the backward / swap step (``fit``), its comparison with
    the data, the current model's blocked CV error before it (nan: not valid), the earlier
    additions that step removed or swapped out (``removed``), what it found, in words
    (``backward``), the effects in the model after it (``in_model``), and the coordinates
    held since the baseline that the model after it determines and frees again
    (``released``, :func:`fitting._diagnose.selection.release_held`). A ``refinement`` step
    adds no effect: it refines the law's pivots (:mod:`fitting._diagnose.refinement`), and
    ``candidates`` is the ranking against the model before it (none significant)."""

    added: str
    candidates: tuple[CandidateRanking, ...]
    fit: FitResult
    comparison: Comparison
    current_cv_rmse_N: float
    removed: tuple[str, ...] = ()
    backward: tuple[str, ...] = ()
    in_model: tuple[str, ...] = ()
    released: tuple[str, ...] = ()
    refinement: bool = False
    refined_cv_rmse_N: float = math.nan

    @property
    def cv_rmse_N(self) -> float:
        """The blocked CV error of the model after this step [N] (nan: not valid)."""
        return self.refined_cv_rmse_N if self.refinement else self.candidates[0].cv_rmse_N


@dataclasses.dataclass(frozen=True)
class Diagnosis:
    """Result of :func:`diagnose`.

    baseline / baseline_comparison: the fit without any candidate; steps: the additions in
    order; final / final_comparison: the last model; final_candidates: the ranking of the
    remaining candidates against it (none significant, or ``max_additions`` reached);
    verdict: the effects in the final model, in the order added (an addition the backward
    step removed is not in it; a swapped-in one takes its place); statements: the verdict
    and caveats in words; noise_given: whether the user gave the noise (else it was
    estimated from the data); noise_estimate: the model-free estimate with its standard
    error (None when the noise was given).
    """

    baseline: FitResult
    baseline_comparison: Comparison
    baseline_cv_rmse_N: float
    steps: tuple[DiagnosisStep, ...]
    final_candidates: tuple[CandidateRanking, ...]
    final_cv_rmse_N: float
    verdict: tuple[str, ...]
    statements: tuple[str, ...]
    candidates: tuple[str, ...]
    stop_reason: str
    noise_given: bool
    options: DiagnoseOptions
    noise_estimate: NoiseEstimate | None = None
    baseline_restart: BaselineRestart | None = None

    @property
    def final(self) -> FitResult:
        return self.steps[-1].fit if self.steps else self.baseline

    @property
    def final_comparison(self) -> Comparison:
        return self.steps[-1].comparison if self.steps else self.baseline_comparison

    @property
    def noise(self) -> float:
        return self.baseline.noise

    def report(self) -> str:
        """The text ``jaxtube diagnose`` prints and writes to ``report.txt``: where the
        baseline fails, the ranking at each step, the before/after table, the verdict."""
        return diagnosis_report(self)

    def to_json(self) -> dict:
        def model(result: FitResult, comparison: Comparison, cv: float) -> dict:
            return {"rmse_N": result.rmse, "chi2": chi2(result), "cv_rmse_N": cv,
                    "bic": chi2(result) + len(result.problem.free_index)
                    * math.log(point_count(result)),
                    "free_parameters": len(result.problem.free_index),
                    "effects": _effect_values(result),
                    "converged": result.convergence.converged,
                    "comparison": comparison.to_json()}

        return {
            "format": "jaxtube-diagnosis", "version": 1,
            "data": str(self.baseline.problem.data.source),
            "noise_N": self.noise, "noise_given": self.noise_given,
            "noise_standard_error_N": (self.noise_estimate.standard_error_N
                                       if self.noise_estimate is not None else None),
            "points": point_count(self.baseline),
            "candidates_considered": list(self.candidates),
            "baseline": model(self.baseline, self.baseline_comparison, self.baseline_cv_rmse_N),
            "baseline_restart": (self.baseline_restart.to_json()
                                 if self.baseline_restart is not None else None),
            "steps": [{"added": s.added, "rmse_N": s.fit.rmse, "removed": list(s.removed),
                       "in_model": list(s.in_model), "backward": list(s.backward),
                       "released": list(s.released), "refinement": s.refinement,
                       "pivots_per_regime": list(s.fit.problem.scaling.pivots_per_regime),
                       "candidates": [c.to_json() for c in s.candidates],
                       "model": model(s.fit, s.comparison, s.cv_rmse_N)}
                      for s in self.steps],
            "verdict": list(self.verdict),
            "statements": list(self.statements),
            "stop_reason": self.stop_reason,
            "rules": {"alpha": self.options.alpha, "bic_threshold": self.options.bic_threshold,
                      "max_additions": self.options.max_additions},
            "final": dict(model(self.final, self.final_comparison, self.final_cv_rmse_N),
                          candidates=[c.to_json() for c in self.final_candidates]),
        }


def diagnose(data: MeasuredData, user_effects: Sequence[type[Effect]] = (),
             scaling: PivotScaling | None = None, rig: CantileverRig | None = None,
             options: DiagnoseOptions | None = None, candidates=None) -> Diagnosis:
    """The whole loop: baseline fit, comparison, ranking, additions (module docstring).

    ``user_effects``: extra candidate classes; ``candidates``: replace the default list
    (:func:`default_candidates`) entirely.
    """
    scaling = scaling or PivotScaling()
    options = options or DiagnoseOptions()
    candidates = tuple(candidates) if candidates is not None else default_candidates(
        scaling, user_effects)
    if not candidates:
        raise ValueError("no candidates to diagnose")
    if options.baseline_starts < 1:
        raise ValueError(f"baseline_starts must be >= 1, got {options.baseline_starts}")
    held = {name: p.null for c in candidates
            for name, p in zip(parameter_names(c), c.parameters)}
    # One noise for every model: the user's, or the model-free estimate. Given to every fit,
    # so uncertainties are in the units of that noise and not inflated by a misfit.
    noise_estimate = (estimate_noise_with_error(data, options.noise_order)
                      if options.noise_N is None else None)
    if options.noise_N is None and noise_estimate is None:
        raise ValueError(f"{data.source}: too few points per curve to estimate the noise (at "
                         "least three are needed); give it (noise_N)")
    noise = noise_estimate.noise_N if noise_estimate is not None else float(options.noise_N)
    fit_options = dataclasses.replace(
        _fit_options(options, noise, options.baseline_iterations), fixed=held)
    problem = make_problem(data, scaling, rig, fit_options, effects=candidates)
    bar = None
    if options.progress:
        from tqdm.auto import tqdm  # lazy: only a diagnosis that shows progress needs it
        bar = tqdm(total=1 + len(candidates) * (1 + min(options.max_additions,
                                                        len(candidates))),
                   desc="diagnose (fits)", unit="fit", leave=False)
    try:
        if bar is not None:
            bar.set_postfix_str("baseline")
        baseline = fit_problem(problem, fit_options)
        # A first fit that ends on its box stopped at the box, not at the law's optimum:
        # restart it and keep the best (restart.py).
        baseline, restart = restart_on_box(baseline, fit_options, options.baseline_starts)
        # Coordinates the data do not determine only drift (they change chi^2 by less than
        # noise) and make every refit slow: hold them at their baseline values from here on.
        baseline, still_held = hold_undetermined_where_left(baseline, fit_options)
        # Every ranking starts from its model's optimum (selection.settle).
        settling = dataclasses.replace(fit_options, max_iterations=options.refit_iterations)
        baseline = settle(baseline, settling)
        if bar is not None:
            bar.update(1)
        baseline_comparison = compare(baseline)
        current, comparison_now = baseline, baseline_comparison
        remaining = list(candidates)
        steps = []
        in_model: list[str] = []
        by_name = {c.name: c for c in candidates}
        n_points = point_count(baseline)
        ranking, cv_now = rank_candidates(current, remaining, options, bar)
        baseline_cv = cv_now
        stop_reason = ""
        refinement_words: list[str] = []
        while True:
            best = ranking[0] if ranking and ranking[0].significant else None
            if best is None and options.refine_pivots and comparison_now.verdict.systematic \
                    and sum(step.refinement for step in steps) < PIVOT_REFINEMENTS:
                refined, held_refined, words = refine_pivots(current, in_model, by_name, data, rig,
                                               fit_options, candidates,
                                               options.bic_threshold, n_points)
                if refined is not None:
                    current = settle(refined, settling)
                    comparison_now = compare(current)
                    still_held = list(held_refined)
                    refined_cv = blocked_cross_validation(current).rmse_N
                    steps.append(DiagnosisStep(
                        added="pivot_refinement", candidates=tuple(ranking), fit=current,
                        comparison=comparison_now, current_cv_rmse_N=cv_now,
                        backward=tuple(words), in_model=tuple(in_model), refinement=True,
                        refined_cv_rmse_N=refined_cv))
                    if remaining:
                        ranking, cv_now = rank_candidates(current, remaining, options, bar)
                        continue
                    ranking, cv_now = [], refined_cv
                else:
                    refinement_words = words
            if best is None:
                stop_reason = "no remaining candidate is significant"
                break
            # Polish the chosen model to the baseline's tolerance, so the next ranking's
            # refits gain nothing by merely finishing its convergence.
            polish = dataclasses.replace(fit_options, max_iterations=options.baseline_iterations)
            current = best.fit if best.fit.convergence.converged else fit_problem(
                best.fit.problem.with_free(best.fit.problem.free_names, best.fit.vector),
                polish)
            in_model.append(best.effect)
            current, removed, backward = backward_step(
                current, in_model, steps, best, by_name, held, options, polish, n_points)
            current, released, words = release_held(current, still_held, polish, n_points)
            still_held = [n for n in still_held if n not in released]
            backward = list(backward) + words
            current = settle(current, settling)
            # Removed or swapped-out effects do not come back (no cycles); swapped-in ones
            # are in the model.
            remaining = [c for c in remaining if c.name != best.effect
                         and c.name not in in_model]
            comparison_now = compare(current)
            steps.append(DiagnosisStep(added=best.effect, candidates=tuple(ranking),
                                       fit=current, comparison=comparison_now,
                                       current_cv_rmse_N=cv_now, removed=tuple(removed),
                                       backward=tuple(backward), in_model=tuple(in_model),
                                       released=tuple(released)))
            additions = sum(not step.refinement for step in steps)
            if not remaining or additions >= options.max_additions:
                ranking, cv_now = [], blocked_cross_validation(current).rmse_N
                stop_reason = ("every candidate was added" if not remaining else
                               f"max_additions ({options.max_additions}) reached; the rest "
                               "were not ranked against the last model")
                break
            ranking, cv_now = rank_candidates(current, remaining, options, bar)
    finally:
        if bar is not None:
            bar.close()
    verdict = tuple(in_model)
    statements = verdict_words(baseline, baseline_comparison, steps, verdict, comparison_now,
                               ranking, candidates)
    statements += separation_statements(current, remaining, ranking) if ranking else []
    statements += refinement_words
    statements += [w for step in steps if step.refinement for w in step.backward]
    statements.append(noise_words(noise, noise_estimate, current))
    for model in (baseline, current):
        validation = blocked_cross_validation(model)
        if not validation.valid:
            statements.append("Cross-validation left out of the decision: "
                              + validation.words + ".")
            break
    if still_held:
        statements.append(
            ("Held in the refined law where its first fit left them" if any(
                step.refinement for step in steps) else "Held at their baseline values "
             "throughout") + " (the data do not determine them, so they would only drift): "
            f"{', '.join(still_held)}.")
    for step in steps:
        if step.released:
            statements.append(
                f"Held from the baseline until {step.added} was added, then determined and "
                f"freed again: {', '.join(step.released)}.")
    return Diagnosis(baseline=baseline, baseline_comparison=baseline_comparison,
                     baseline_cv_rmse_N=baseline_cv, steps=tuple(steps),
                     final_candidates=tuple(ranking), final_cv_rmse_N=cv_now,
                     verdict=verdict, statements=tuple(statements),
                     candidates=tuple(c.name for c in candidates), stop_reason=stop_reason,
                     noise_given=options.noise_N is not None, options=options,
                     noise_estimate=noise_estimate, baseline_restart=restart)


__all__ = ["Diagnosis", "DiagnosisStep", "diagnose"]
