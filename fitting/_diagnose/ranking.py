"""Which effect is missing: score tests, refits, ranking and the iterative diagnosis.

The candidates are effects (:class:`fitting.Effect`): the built-in physical effects, the
model-structure extension ``radius_scaling``, and any the user passes. All are compiled into
one model at their null values, so the baseline fit, every score test and every refit share
one compilation per data shape; which coordinates are free is chosen on the host.

**Score test at the null** (Rao 1948; Boos & Stefanski, *Essential Statistical Inference*,
2013, section 6.4). For a fit in which the candidate's parameters are held at their null
values, with ``r`` the residuals in noise units, ``J_b`` the Jacobian columns of the fitted
coordinates and ``J_c`` those of the candidate's::

    U = -J_c^T r                                        (score)
    I = J_c^T J_c - J_c^T J_b (J_b^T J_b)^+ J_b^T J_c   (efficient information)
    S = U^T I^+ U  ~  chi^2_q under the null

It needs no refit. Effects bounded at their null (a stiffness, a compliance, a mass cannot be
negative) make a single-parameter test one-sided: ``S = 0`` when the score points out of the
feasible side, and the p-value is half the chi^2_1 tail (Self & Liang 1987).

**Refit** with the candidate freed, from the current optimum: the error drop, ``Delta chi^2``,
``Delta BIC = Delta chi^2 + q ln n`` (Schwarz 1978; chi^2 in units of the one noise estimate
of the baseline, so all models are compared on the same scale), ``Delta AIC = Delta chi^2 +
2 q``, and the leave-one-curve-out error. The cross-validation is linearised: for each curve
the refit without it is one Gauss-Newton step from the full-data optimum (the standard
one-step approximation of a case-deletion refit, e.g. Cook & Weisberg, *Residuals and
Influence in Regression*, 1982, section 5.4), and the held-out curve is predicted from it.

**Significance** (all three must hold): the score test rejects at ``alpha`` (default 1 %)
after a Bonferroni correction over the candidates still in play; the refit lowers the BIC by
more than ``bic_threshold`` (default 10, "very strong" on the scale of Kass & Raftery 1995);
and it lowers the cross-validated error. An extra parameter always lowers the training error;
these rules keep that from being claimed as an effect.

**Iteration.** Add the significant candidate with the lowest BIC, refit, re-rank the rest from
the new model, and stop when none is significant (or ``max_additions`` is reached).

**Cannot be told apart.** At each model, each candidate's effect on the curves that the
current parameters cannot absorb is ``(I - P_b) J_c`` (``P_b`` the projection onto the fitted
columns). Its share ``||(I - P_b) J_c||^2 / ||J_c||^2`` below :data:`ABSORBED_SHARE` means the
pivots reproduce the effect with this data; a canonical correlation above
:data:`CONFOUNDED_CORRELATION` between two candidates' absorbed-free effects means they change
the curves the same way. Either is reported in words, with the specimen quantities that would
separate them (``Effect.separated_by``) and whether the data vary them.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

from .._bench.effects import BUILT_IN_EFFECTS, MODEL_EXTENSIONS, Effect
from .._bench.rig import CantileverRig
from .._bench.scaling import PivotScaling
from .._calibrate.fit import fit_problem
from .._calibrate.problem import FitError, FitOptions, estimate_noise, make_problem
from .._calibrate.result import FitResult
from .._data import MeasuredData
from .._json import finite_or_none
from .compare import Comparison, compare
from .report import diagnosis_report
from .score import (
    _share,
    absorbed_free_effects,
    chi2,
    cross_validated_rmse,
    parameter_names,
    point_count,
    score_test,
)
from .separation import (
    _effect_values,
    _separation_advice,
    _spread_words,
    separation_statements,
)

#: Two significant candidates whose BIC drops differ by less than this explain the data
#: about equally well ("very strong" evidence starts at 10: Kass & Raftery 1995).
CLOSE_BIC = 10.0


# --------------------------------------------------------------------------------------------
# Score test
# --------------------------------------------------------------------------------------------


# --------------------------------------------------------------------------------------------


def default_candidates(scaling: PivotScaling, user_effects: Sequence[type[Effect]] = ()):
    """The diagnosis' candidates: ``radius_scaling`` (paper form only), the built-in
    physical effects, then the user's, in that order (laws are modified before
    reinforcement wraps them)."""
    extensions = tuple(MODEL_EXTENSIONS.values()) if scaling.form == "paper" else ()
    candidates = extensions + tuple(BUILT_IN_EFFECTS.values())
    names = [c.name for c in candidates]
    for effect in user_effects:
        if effect.name in names:
            raise ValueError(f"effect name {effect.name!r} is taken; rename the user effect")
        names.append(effect.name)
    return candidates + tuple(user_effects)


@dataclasses.dataclass(frozen=True)
class CandidateRanking:
    """One candidate evaluated against the current model.

    effect, kind; parameters: their names; score_statistic, score_p_value: the score test at
    the null; rmse_N, chi2, delta_chi2, delta_bic, delta_aic, cv_rmse_N: of the refit with
    the candidate freed (deltas against the current model); estimates: the refit's values of
    the candidate's parameters; significant: all three rules of the module docstring hold;
    reasons: why not, in words; unabsorbed_share: the share of its effect the current
    parameters cannot absorb (1: none of it is absorbed); fit: the refit (not serialised).
    """

    effect: str
    kind: str
    parameters: tuple[str, ...]
    score_statistic: float
    score_p_value: float
    rmse_N: float
    chi2: float
    delta_chi2: float
    delta_bic: float
    delta_aic: float
    cv_rmse_N: float
    estimates: dict
    significant: bool
    reasons: tuple[str, ...]
    unabsorbed_share: float
    fit: FitResult = dataclasses.field(repr=False, compare=False)

    def to_json(self) -> dict:
        row = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "fit"}
        row["parameters"] = list(self.parameters)
        row["reasons"] = list(self.reasons)
        return {k: finite_or_none(v) if isinstance(v, float) else v for k, v in row.items()}


@dataclasses.dataclass(frozen=True)
class DiagnoseOptions:
    """Choices of the diagnosis (see the module docstring).

    alpha: family-wise level of the score tests; bic_threshold: the BIC drop a candidate
    must exceed; max_additions; noise_N: the force noise [N] (None: estimated once from the
    data, model-free, and used by every model); baseline_iterations / refit_iterations:
    Levenberg-Marquardt caps; chi2_tol: a fit stops when chi^2 (noise units) falls by less
    than this per iteration; progress: progress bars.
    """

    alpha: float = 0.01
    bic_threshold: float = 10.0
    max_additions: int = 3
    noise_N: float | None = None
    baseline_iterations: int = 40
    refit_iterations: int = 15
    chi2_tol: float = 0.05
    progress: bool = True


def _fit_options(options: DiagnoseOptions, noise, iterations) -> FitOptions:
    return FitOptions(noise_N=noise, max_iterations=iterations, chi2_tol=options.chi2_tol,
                      ftol=1e-9, progress=False)


def rank_candidates(current: FitResult, candidates, options: DiagnoseOptions, bar=None):
    """Evaluate every candidate against ``current`` (score test, refit, BIC, CV), best
    first: significant ones by BIC, then the rest by BIC."""
    n = point_count(current)
    chi2_now = chi2(current)
    cv_now = cross_validated_rmse(current)
    alpha = options.alpha / max(len(candidates), 1)
    effects = absorbed_free_effects(current, candidates)
    fit_options = _fit_options(options, current.noise, options.refit_iterations)
    rows = []
    for effect in candidates:
        names = parameter_names(effect)
        if bar is not None:
            bar.set_postfix_str(effect.name)
        test = score_test(current, names)
        problem = current.problem.with_free(current.problem.free_names + list(names),
                                            current.vector)
        try:
            refit = fit_problem(problem, fit_options)
        except FitError as error:  # reported as a failed candidate, never dropped silently
            refit, failure = None, str(error)
        if bar is not None:
            bar.update(1)
        if refit is None:
            rows.append(_failed_candidate(effect, names, test, failure, current))
            continue
        chi2_new = chi2(refit)
        q = len(names)
        delta = chi2_new - chi2_now
        delta_bic = delta + q * math.log(n)
        cv = cross_validated_rmse(refit)
        reasons = []
        if not test.p_value < alpha:
            reasons.append(f"score test not significant (p = {test.p_value:.2g} >= "
                           f"{alpha:.2g})")
        if not delta_bic < -options.bic_threshold:
            reasons.append(f"BIC drop {-delta_bic:.3g} <= {options.bic_threshold:g}")
        if not cv < cv_now:
            reasons.append(f"cross-validated error does not fall ({cv:.4g} N >= "
                           f"{cv_now:.4g} N)")
        residual_part, whole = effects[effect.name]
        rows.append(CandidateRanking(
            effect=effect.name, kind=effect.kind, parameters=names,
            score_statistic=test.statistic, score_p_value=test.p_value, rmse_N=refit.rmse,
            chi2=chi2_new, delta_chi2=delta, delta_bic=delta_bic, delta_aic=delta + 2 * q,
            cv_rmse_N=cv, estimates={name: float(refit.vector[problem.names.index(name)])
                                     for name in names},
            significant=not reasons, reasons=tuple(reasons),
            unabsorbed_share=_share(residual_part, whole), fit=refit))
    rows.sort(key=lambda row: (not row.significant, row.delta_bic))
    return rows, cv_now


def _failed_candidate(effect, names, test, failure, current) -> CandidateRanking:
    nan = math.nan
    return CandidateRanking(
        effect=effect.name, kind=effect.kind, parameters=names,
        score_statistic=test.statistic, score_p_value=test.p_value, rmse_N=nan, chi2=nan,
        delta_chi2=nan, delta_bic=math.inf, delta_aic=math.inf, cv_rmse_N=nan, estimates={},
        significant=False, reasons=(f"the refit failed: {failure}",), unabsorbed_share=nan,
        fit=current)


# --------------------------------------------------------------------------------------------
# The diagnosis
# --------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class DiagnosisStep:
    """One addition: ``added`` (effect name), the ranking that chose it (best first), the
    model after adding it (``fit``) and its comparison with the data."""

    added: str
    candidates: tuple[CandidateRanking, ...]
    fit: FitResult
    comparison: Comparison
    current_cv_rmse_N: float


@dataclasses.dataclass(frozen=True)
class Diagnosis:
    """Result of :func:`diagnose`.

    baseline / baseline_comparison: the fit without any candidate; steps: the additions in
    order; final / final_comparison: the last model; final_candidates: the ranking of the
    remaining candidates against it (none significant, or ``max_additions`` reached);
    verdict: the names added, in order; statements: the verdict and caveats in words;
    noise_given: whether the user gave the noise (else it was estimated from the data).
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
            "points": point_count(self.baseline),
            "candidates_considered": list(self.candidates),
            "baseline": model(self.baseline, self.baseline_comparison, self.baseline_cv_rmse_N),
            "steps": [{"added": s.added, "rmse_N": s.fit.rmse,
                       "candidates": [c.to_json() for c in s.candidates],
                       "model": model(s.fit, s.comparison, s.candidates[0].cv_rmse_N)}
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
    held = {name: p.null for c in candidates
            for name, p in zip(parameter_names(c), c.parameters)}
    # One noise for every model: the user's, or the model-free estimate. Given to every fit,
    # so uncertainties are in the units of that noise and not inflated by a misfit.
    noise = estimate_noise(data) if options.noise_N is None else float(options.noise_N)
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
        # Coordinates the data do not determine only drift (they change chi^2 by less than
        # noise) and make every refit slow: hold them at their baseline values from here on.
        undetermined = [name for name, se in zip(baseline.problem.free_names,
                                                 baseline.free_standard_errors)
                        if not math.isfinite(se)]
        if undetermined:
            kept = [n for n in baseline.problem.free_names if n not in undetermined]
            baseline = fit_problem(baseline.problem.with_free(kept, baseline.vector),
                                   fit_options)
        if bar is not None:
            bar.update(1)
        baseline_comparison = compare(baseline)
        current, comparison_now = baseline, baseline_comparison
        remaining = list(candidates)
        steps = []
        ranking, cv_now = rank_candidates(current, remaining, options, bar)
        baseline_cv = cv_now
        stop_reason = ""
        while True:
            best = ranking[0] if ranking and ranking[0].significant else None
            if best is None:
                stop_reason = "no remaining candidate is significant"
                break
            # Polish the chosen model to the baseline's tolerance, so the next ranking's
            # refits gain nothing by merely finishing its convergence.
            polish = dataclasses.replace(fit_options, max_iterations=options.baseline_iterations)
            current = best.fit if best.fit.convergence.converged else fit_problem(
                best.fit.problem.with_free(best.fit.problem.free_names, best.fit.vector),
                polish)
            comparison_now = compare(current)
            steps.append(DiagnosisStep(added=best.effect, candidates=tuple(ranking),
                                       fit=current, comparison=comparison_now,
                                       current_cv_rmse_N=cv_now))
            remaining = [c for c in remaining if c.name != best.effect]
            if not remaining or len(steps) >= options.max_additions:
                ranking, cv_now = [], cross_validated_rmse(current)
                stop_reason = ("every candidate was added" if not remaining else
                               f"max_additions ({options.max_additions}) reached; the rest "
                               "were not ranked against the last model")
                break
            ranking, cv_now = rank_candidates(current, remaining, options, bar)
    finally:
        if bar is not None:
            bar.close()
    verdict = tuple(step.added for step in steps)
    statements = _verdict_words(baseline, baseline_comparison, steps, comparison_now, ranking,
                                candidates)
    statements += separation_statements(current, remaining, ranking) if ranking else []
    if undetermined:
        statements.append(
            "Held at their baseline values throughout (the data do not determine them, so "
            f"they would only drift): {', '.join(undetermined)}.")
    return Diagnosis(baseline=baseline, baseline_comparison=baseline_comparison,
                     baseline_cv_rmse_N=baseline_cv, steps=tuple(steps),
                     final_candidates=tuple(ranking), final_cv_rmse_N=cv_now,
                     verdict=verdict, statements=tuple(statements),
                     candidates=tuple(c.name for c in candidates), stop_reason=stop_reason,
                     noise_given=options.noise_N is not None, options=options)


def _verdict_words(baseline, baseline_comparison, steps, final_comparison, ranking,
                   candidates):
    noise = baseline.noise
    by_name = {c.name: c for c in candidates}
    words = []
    if not steps:
        if baseline_comparison.verdict.systematic:
            words.append(
                f"Nothing among the candidates is missing, yet the residuals are systematic "
                f"(RMSE {baseline.rmse:.3g} N, noise {noise:.3g} N): the missing physics is "
                "not among the candidates. Write it as an effect (see the README) and pass it "
                "with --effect FILE.py:Class.")
        else:
            words.append(
                f"Nothing is missing: the model explains the data to within the noise (RMSE "
                f"{baseline.rmse:.3g} N, noise {noise:.3g} N) and no candidate is significant.")
    else:
        final = steps[-1].fit
        for step in steps:
            row = step.candidates[0]
            values = ", ".join(f"{k.split('.', 1)[1]} = {v:.4g}" for k, v in row.estimates.items())
            words.append(
                f"Missing: {step.added} ({values}): score test S = {row.score_statistic:.3g} "
                f"(p = {row.score_p_value:.2g}), ΔBIC {row.delta_bic:.1f}, cross-validated "
                f"error {step.current_cv_rmse_N:.3g} -> {row.cv_rmse_N:.3g} N.")
            for rival in step.candidates[1:]:
                if rival.significant and rival.delta_bic - row.delta_bic < CLOSE_BIC:
                    pair = [by_name[step.added], by_name[rival.effect]]
                    quantities = tuple(dict.fromkeys(q for e in pair for q in e.separated_by))
                    _, fixed = _spread_words(baseline.problem.data, quantities)
                    words.append(
                        f"{step.added} and {rival.effect} can barely be told apart with this "
                        f"data: either alone explains it (ΔBIC {row.delta_bic:.1f} and "
                        f"{rival.delta_bic:.1f}, a difference under {CLOSE_BIC:g}; "
                        f"cross-validated error {row.cv_rmse_N:.3g} and {rival.cv_rmse_N:.3g} "
                        f"N). {step.added} is kept for its lower BIC; check that its value is "
                        f"plausible. " + _separation_advice(pair, fixed))
        words.append(
            f"With {', '.join(s.added for s in steps)} the RMSE falls from {baseline.rmse:.3g} "
            f"N to {final.rmse:.3g} N (noise {noise:.3g} N). "
            + ("The remaining residuals are noise." if not final_comparison.verdict.systematic
               else "The remaining residuals are still systematic: "
               + final_comparison.verdict.words))
    close = [row for row in ranking if not row.significant and row.score_p_value < 0.01]
    for row in close:
        words.append(f"{row.effect} has a significant score but is not added: "
                     + "; ".join(row.reasons) + ".")
    return words


__all__ = ["CandidateRanking", "Diagnosis", "DiagnosisStep", "DiagnoseOptions",
           "default_candidates", "diagnose", "rank_candidates"]
