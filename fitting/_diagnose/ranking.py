"""Which effect is missing: score tests, refits, the decision rule and the ranking.

The candidates are effects (:class:`fitting.Effect`): the built-in physical effects, the
model-structure extensions ``radius_scaling`` and ``unwrinkled_linearity``, and any the user
passes. All are compiled into one model at their null values, so the baseline fit, every
score test and every refit share one compilation per data shape; which coordinates are free
is chosen on the host. The loop over additions is :mod:`fitting._diagnose.diagnosis`.

**Score test at the null** (Rao 1948; Boos & Stefanski, *Essential Statistical Inference*,
2013, section 6.4), used only to order the refits. For a fit in which the candidate's
parameters are held at their null values, with ``r`` the residuals in noise units, ``J_b``
the Jacobian columns of the fitted coordinates and ``J_c`` those of the candidate's::

    U = -J_c^T r                                        (score)
    I = J_c^T J_c - J_c^T J_b (J_b^T J_b)^+ J_b^T J_c   (efficient information)
    S = U^T I^+ U  ~  chi^2_q under the null

Effects bounded at their null (a stiffness, a compliance, a mass cannot be negative) make a
single-parameter test one-sided: ``S = 0`` when the score points out of the feasible side
(Self & Liang 1987). The test is local: at a null on a bound the first-order direction can
point out of the feasible set while the refit, with the pivots moving along, finds a large
improvement inside it. So it never vetoes a candidate.

**Refit** with the candidate freed, from the current optimum, starting from the candidate's
null and, unless that refit ended inside its box past the typical size (it may have stalled
on a null that is a bound, stopped in a local minimum on the way, or gone to the far edge
of its box, a basin other than the physical one), again from its typical size; the better
refit is kept (:func:`fitting._diagnose.selection.refit_candidate`). From it:
``Delta chi^2``, ``Delta BIC = Delta chi^2 + q ln n`` (Schwarz 1978; chi^2 in units of the
one noise estimate, so all models are compared on the same scale),
``Delta AIC = Delta chi^2 + 2 q``, and the blocked cross-validated error.

**Likelihood-ratio test** (the decision): ``LR = chi^2_current - chi^2_refit`` against
``chi^2_q``, or, for parameters whose null is on a bound, the mixture ``0.5 chi^2_0 + 0.5
chi^2_1`` per bounded parameter (Chernoff 1954; Self & Liang 1987;
:func:`fitting._diagnose.score.likelihood_ratio_p_value`).

**Evidence against a model that still misses** (quasi-likelihood: Wedderburn 1974; McCullagh
& Nelder, *Generalized Linear Models*, 1989, section 9.2; the same ``c`` as QAIC, Burnham &
Anderson 2002, section 2.5): the tests assume that the larger model is right, so that its
residuals are the noise. When even the best refit of a step leaves a residual scatter above
the noise (``c = chi^2 / dof > 1``: the bending-law family cannot follow the truth, or the
noise is underestimated), any extra flexibility lowers chi^2 by about ``c`` per parameter
and a chi^2 drop in noise units overstates the evidence by ``c``. So ``LR``, ``Delta BIC``
and ``Delta AIC`` are divided by ``c = max(1, min over the step's refits of chi^2 / dof)``,
one ``c`` for the whole step (the ranking's order is unchanged); the backward / swap step
uses the current model's ``c``. Where a refit reaches the noise, ``c = 1`` and nothing
changes.

**Cross-validation** over blocks of points within curves: each curve is cut into four
contiguous blocks and fold ``k`` holds out block ``k + c mod 4`` of curve ``c``, so every
fold keeps every specimen; each fold's refit is the case-deletion estimate from the optimum
(:mod:`fitting._diagnose.validation`). When a fold's leverage shows that the remaining
points do not determine the parameters, the cross-validated error is left out of the
decision, and the report says so.

**Significance** (all must hold): the likelihood-ratio test rejects at ``alpha`` (default
1 %) after a Bonferroni correction over the candidates still in play; the refit lowers the
BIC by more than ``bic_threshold`` (default 10, "very strong" on the scale of Kass & Raftery
1995); the cross-validated error does not rise beyond its scatter (when valid: the paired
mean of the points' held-out squared errors, against the current model's, is not more than
``CV_RISE_Z`` standard errors above zero); and the fitted size is within the
effect's plausible range (:class:`fitting.EffectParameter` ``plausible``): an effect that
explains the data only at an implausible size is reported as such and is not the verdict.
An extra parameter always lowers the training error; the BIC and the cross-validation keep
that from being claimed as an effect. Every candidate records which rules decided
(``decided_by``).

**Cannot be told apart.** At each model, each candidate's effect on the curves that the
current parameters cannot absorb is ``(I - P_b) J_c`` (``P_b`` the projection onto the fitted
columns). Its share ``||(I - P_b) J_c||^2 / ||J_c||^2`` below ``ABSORBED_SHARE`` means the
pivots reproduce the effect with this data; a canonical correlation above
``CONFOUNDED_CORRELATION`` between two candidates' absorbed-free effects means they change the
curves the same way (both in :mod:`fitting._diagnose.separation`). Either is reported in
words, with the specimen quantities that would separate them (``Effect.separated_by``) and
whether the data vary them.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

from .._bench.effects import BUILT_IN_EFFECTS, MODEL_EXTENSIONS, Effect
from .._bench.scaling import PivotScaling
from .._calibrate.noise import DEFAULT_ORDER
from .._calibrate.problem import FitOptions
from .._calibrate.result import FitResult
from .._json import finite_or_none
from .score import (
    _share,
    absorbed_free_effects,
    chi2,
    dispersion,
    likelihood_ratio_p_value,
    parameter_names,
    point_count,
    score_test,
)
from .selection import bound_count, implausible_words, refit_candidate
from .validation import CV_RISE_Z, blocked_cross_validation


def default_candidates(scaling: PivotScaling, user_effects: Sequence[type[Effect]] = ()):
    """The diagnosis' candidates: the model-structure extensions that act on the
    scaling's form (``radius_scaling`` on the paper form only), the built-in physical
    effects, then the user's, in that order (laws are modified before reinforcement wraps
    them)."""
    extensions = tuple(cls for cls in MODEL_EXTENSIONS.values() if scaling.form in cls.forms)
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
    the candidate's parameters; significant: every rule of the module docstring holds;
    reasons: why not, in words; unabsorbed_share: the share of its effect the current
    parameters cannot absorb (1: none of it is absorbed); fit: the refit (not serialised);
    lr_statistic, lr_p_value: the likelihood-ratio test on the refit (the decision);
    plausible: its fitted size is within the effect's plausible range; decided_by: which
    rules decided, in words; dispersion: the ``c`` that ``lr_statistic``, ``delta_bic`` and
    ``delta_aic`` are divided by (``delta_chi2`` / ``c``; 1 when the best refit's residuals
    are the noise; module docstring).
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
    lr_statistic: float = math.nan
    lr_p_value: float = math.nan
    plausible: bool = True
    decided_by: str = ""
    dispersion: float = 1.0

    def to_json(self) -> dict:
        row = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "fit"}
        row["parameters"] = list(self.parameters)
        row["reasons"] = list(self.reasons)
        return {k: finite_or_none(v) if isinstance(v, float) else v for k, v in row.items()}


@dataclasses.dataclass(frozen=True)
class DiagnoseOptions:
    """Choices of the diagnosis (see the module docstring).

    alpha: family-wise level of the likelihood-ratio tests; bic_threshold: the BIC drop a candidate
    must exceed; max_additions; noise_N: the force noise [N] (None: estimated once from the
    data, model-free, and used by every model); baseline_iterations / refit_iterations:
    Levenberg-Marquardt caps; chi2_tol: a fit stops when chi^2 (noise units) falls by less
    than this per iteration; refine_pivots: when no candidate is significant and the
    residuals are still systematic, try the law with one more unwrinkled and wrinkled pivot
    (:mod:`fitting._diagnose.refinement`); baseline_starts: starts of the baseline's fit
    when its first fit ends with coordinates on their box bounds (the first fit included; the
    fit of lowest chi^2 is kept; :mod:`fitting._diagnose.restart`); default 1, no restart
    (why: docs/diagnosis-study.md, "The baseline's basin"); noise_order: the polynomial
    degree the model-free noise estimate's differences annihilate
    (:func:`fitting.estimate_noise_with_error`); progress: progress bars.
    """

    alpha: float = 0.01
    bic_threshold: float = 10.0
    max_additions: int = 3
    noise_N: float | None = None
    baseline_iterations: int = 40
    refit_iterations: int = 15
    chi2_tol: float = 0.05
    refine_pivots: bool = True
    baseline_starts: int = 1
    noise_order: int = DEFAULT_ORDER
    progress: bool = True


def _fit_options(options: DiagnoseOptions, noise, iterations) -> FitOptions:
    return FitOptions(noise_N=noise, max_iterations=iterations, chi2_tol=options.chi2_tol,
                      ftol=1e-9, progress=False)


def rank_candidates(current: FitResult, candidates, options: DiagnoseOptions, bar=None):
    """Evaluate every candidate against ``current`` (score test, refit, likelihood ratio,
    BIC, CV, plausible size; module docstring), best first: significant ones by BIC, then the
    rest by BIC. Returns ``(rows, the current model's blocked CV error [N], nan if not
    valid)``. The score tests only order the refits (most promising first)."""
    n = point_count(current)
    chi2_now = chi2(current)
    cv_now = blocked_cross_validation(current)
    alpha = options.alpha / max(len(candidates), 1)
    effects = absorbed_free_effects(current, candidates)
    fit_options = _fit_options(options, current.noise, options.refit_iterations)
    tests = {effect.name: score_test(current, parameter_names(effect)) for effect in candidates}
    ordered = sorted(candidates, key=lambda e: -tests[e.name].statistic)
    refits = []
    for effect in ordered:
        names = parameter_names(effect)
        if bar is not None:
            bar.set_postfix_str(effect.name)
        problem = current.problem.with_free(current.problem.free_names + list(names),
                                            current.vector)
        refit, failure = refit_candidate(problem, names, effect, fit_options)
        if bar is not None:
            bar.update(1)
        refits.append((effect, names, problem, refit, failure))
    # The evidence is measured in units of the best refit's residual scatter when that
    # exceeds the noise (quasi-likelihood): one c for every candidate of the step.
    c = max(1.0, min((dispersion(r) for *_, r, _ in refits if r is not None), default=1.0))
    rows = []
    for effect, names, problem, refit, failure in refits:
        test = tests[effect.name]
        if refit is None:
            rows.append(_failed_candidate(effect, names, test, failure, current))
            continue
        chi2_new = chi2(refit)
        q = len(names)
        delta = chi2_new - chi2_now
        delta_bic = delta / c + q * math.log(n)
        ratio = max(-delta, 0.0) / c
        lr_p = likelihood_ratio_p_value(ratio, q, bound_count(problem, names))
        cv = blocked_cross_validation(refit)
        estimates = {name: float(refit.vector[problem.names.index(name)]) for name in names}
        reasons, failed = [], []
        units = f" in units of the residual scatter, c = {c:.3g}" if c > 1.0 else ""
        if not lr_p < alpha:
            failed.append("likelihood ratio")
            reasons.append(f"likelihood-ratio test not significant (LR = {ratio:.3g}{units}, "
                           f"p = {lr_p:.2g} >= {alpha:.2g})")
        if not delta_bic < -options.bic_threshold:
            failed.append("BIC")
            reasons.append(f"BIC drop {-delta_bic:.3g} <= {options.bic_threshold:g}"
                           + (f" ({units.strip()})" if units else ""))
        cv_used = cv.valid and cv_now.valid
        rise = cv.rise_z(cv_now)
        if cv_used and rise > CV_RISE_Z:
            failed.append("cross-validation")
            reasons.append(f"cross-validated error rises beyond its scatter ({cv.rmse_N:.4g} "
                           f"N against {cv_now.rmse_N:.4g} N, paired z = {rise:.2g} > "
                           f"{CV_RISE_Z:g})")
        implausible = implausible_words(effect, names, estimates)
        if implausible:
            failed.append("plausible size")
            reasons += implausible
        decided = ("not added: " + ", ".join(failed) if failed else
                   "added if best: likelihood ratio, BIC, "
                   + ("cross-validation" if cv_used else "(cross-validation left out: "
                      + (cv_now.words or cv.words) + ")") + ", plausible size")
        residual_part, whole = effects[effect.name]
        rows.append(CandidateRanking(
            effect=effect.name, kind=effect.kind, parameters=names,
            score_statistic=test.statistic, score_p_value=test.p_value, rmse_N=refit.rmse,
            chi2=chi2_new, delta_chi2=delta, delta_bic=delta_bic, delta_aic=delta / c + 2 * q,
            cv_rmse_N=cv.rmse_N, estimates=estimates,
            significant=not reasons, reasons=tuple(reasons),
            unabsorbed_share=_share(residual_part, whole), fit=refit,
            lr_statistic=ratio, lr_p_value=lr_p, plausible=not implausible,
            decided_by=decided, dispersion=c))
    rows.sort(key=lambda row: (not row.significant, row.delta_bic))
    return rows, cv_now.rmse_N


def _failed_candidate(effect, names, test, failure, current) -> CandidateRanking:
    nan = math.nan
    return CandidateRanking(
        effect=effect.name, kind=effect.kind, parameters=names,
        score_statistic=test.statistic, score_p_value=test.p_value, rmse_N=nan, chi2=nan,
        delta_chi2=nan, delta_bic=math.inf, delta_aic=math.inf, cv_rmse_N=nan, estimates={},
        significant=False, reasons=(f"the refit failed: {failure}",), unabsorbed_share=nan,
        fit=current, decided_by="not added: the refit failed")


__all__ = ["CandidateRanking", "DiagnoseOptions", "default_candidates", "rank_candidates"]
