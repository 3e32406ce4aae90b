"""Which physical effect a kite model misses, from its calibration cases' markers.

**Baseline**: the campaign's model with its baseline values (``[diagnose] baseline``,
default ``bending_scale``) fitted to every calibration case
(:func:`fitting.calibrate_campaign`).

**Ranking by cases not fitted to** (leave one case out): for the current model and for the
current model with each candidate effect (:class:`fitting.ShapeEffect`) freed, the values
are fitted to all cases but one and the left-out case is scored (smooth RMS,
:func:`fitting.smooth_shape_score`); a candidate's *held-out gain* is the fall of the mean
over left-out cases of the squared RMS [mm²]. ``held_out="linearised"`` (the default) takes
each fit to the other cases as one Gauss-Newton step from the fit to every case without the
left-out case's rows (the case-deletion formula of least squares, exact for a model linear
in its values near the optimum), clipped to the bounds, and re-registers the left-out case
in the same linearisation (:func:`linearised_held_out`): no solve beyond the fit to every
case. ``held_out="refit"`` fits the values to the other cases and solves the left-out case
(a fit per case and candidate). Every fit starts from the current model's
values (the last optimum), the candidate's at its null (1 for a factor, 0 for a mass or an
offset, clipped into its plausible range), every solve from the case's last
equilibrium (:class:`fitting.CaseSolver` ``warm_starts``) and every case's registration from
the current fit's.

**Statistics** (as the curve diagnosis, :mod:`fitting._diagnose.ranking`, where they apply):
each candidate is also fitted to every case; with ``RSS`` the tube markers' smooth distances'
sum of squares over ``n`` markers, the noise variance ``s² = RSS_candidate / dof`` (the
larger model's residuals; the registrations count six each), ``Delta chi^2 = (RSS_current -
RSS_candidate) / s²``, the likelihood-ratio p-value against ``chi^2_q`` (``q`` the effect's
values) and the fall of the BIC ``Delta chi^2 - q ln n`` (Schwarz 1978).

**Decision** (all must hold): the held-out gain is positive; the p-value is below ``alpha``
divided by the candidates still in play (Bonferroni); the BIC falls by more than
``BIC_THRESHOLD`` (10, "very strong", Kass & Raftery 1995); no fitted value ends on an edge
of its plausible range (then the data want it beyond what is physical: the effect is not
named); the fit converged. Of the candidates that pass, the one with the largest held-out
gain is added, the model refitted, and the ranking repeated until none passes. Candidates
that pass with a BIC within ``CLOSE_BIC`` of the chosen one are said not to be separated by
the cases.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
from scipy.stats import chi2

from .._json import finite_or_none
from .._shape.markers import load_markers
from .._shape.smooth import smooth_shape_score
from .calibrate import CampaignCalibration, calibrate_campaign, on_bound, value_bounds
from .file import Campaign
from .kite import campaign_tube_surfaces, search_coordinates
from .model import KiteModel
from .solve import CaseSolver

BIC_THRESHOLD = 10.0
#: How a left-out case is scored (module docstring).
HELD_OUT = ("linearised", "refit")
CLOSE_BIC = 10.0
ALPHA = 0.01
#: Gauss-Newton steps per fit (each starts from the last optimum).
FIT_STEPS = 12


@dataclasses.dataclass(frozen=True)
class ShapeCandidateRanking:
    """One candidate at one step.

    Attributes:
        effect: the candidate (:class:`fitting.ShapeEffect`).
        held_out_rms_mm: ``{case: smooth RMS [mm]}`` of each case when fitted to the others.
        held_out_gain_mm2: the fall of the mean square held-out RMS [mm²] against the
            current model's (``nan``: a fit failed).
        delta_chi2, p_value, bic_fall: the statistics of the fit to every case (module
            docstring; ``nan`` when undefined).
        fit: the fit to every case (``None``: it failed).
        reasons: why it is not added (empty: it passes).
    """

    effect: object
    held_out_rms_mm: dict
    held_out_gain_mm2: float
    delta_chi2: float
    p_value: float
    bic_fall: float
    fit: CampaignCalibration | None
    reasons: tuple

    def to_json(self) -> dict:
        fitted = None if self.fit is None else {
            name: {"value": float(v), "standard_error": finite_or_none(e)}
            for name, v, e in zip(self.fit.names, self.fit.values, self.fit.standard_errors)
            if name in self.effect.values}
        return {"effect": self.effect.name, "values": list(self.effect.values),
                "plausible": [list(r) for r in self.effect.plausible],
                "held_out_rms_mm": self.held_out_rms_mm,
                "held_out_gain_mm2": finite_or_none(self.held_out_gain_mm2),
                "delta_chi2": finite_or_none(self.delta_chi2),
                "p_value": finite_or_none(self.p_value),
                "bic_fall": finite_or_none(self.bic_fall), "fitted": fitted,
                "passes": not self.reasons, "reasons": list(self.reasons)}


@dataclasses.dataclass(frozen=True)
class ShapeDiagnosis:
    """A diagnosis' outcome.

    Attributes:
        baseline: the baseline fit; final: the fit the diagnosis ends with.
        added: the effects added, in order.
        steps: per step, ``(current held-out RMS {case: mm}, [ShapeCandidateRanking])``.
        unseparated: statements of what the cases cannot separate.
        verdict: the verdict in words.
    """

    baseline: CampaignCalibration
    final: CampaignCalibration
    added: tuple
    steps: tuple
    unseparated: tuple
    verdict: str

    @property
    def converged(self) -> bool:
        """The final fit converged (every case solved)."""
        return self.final.converged

    def to_json(self) -> dict:
        return {"verdict": self.verdict, "added": [e.name for e in self.added],
                "converged": self.converged, "unseparated": list(self.unseparated),
                "baseline": self.baseline.to_json(), "final": self.final.to_json(),
                "steps": [{"held_out_rms_mm": current,
                           "candidates": [r.to_json() for r in ranking]}
                          for current, ranking in self.steps]}


def diagnose_campaign(campaign: Campaign, model: KiteModel, baseline, candidates, cases,
                      solver: CaseSolver, log=print, bar=None,
                      held_out: str = "linearised") -> ShapeDiagnosis:
    """Diagnose ``model`` on ``cases`` (at least two, each with markers): fit the values
    ``baseline``, then add ``candidates`` (:class:`fitting.ShapeEffect`) by the module
    docstring's rule. ``solver`` should differentiate with respect to every value involved
    (``CaseSolver(campaign, tangent_values=...)``: one compiled program per route);
    ``bar``: an optional progress bar (``update(1)`` per fit); ``held_out``:
    ``"linearised"`` or ``"refit"`` (module docstring)."""
    if held_out not in HELD_OUT:
        raise ValueError(f"held_out: expected one of {', '.join(HELD_OUT)}, found "
                         f"{held_out!r}")
    cases = list(cases)
    if len(cases) < 2:
        raise ValueError(f"diagnose: {len(cases)} calibration case; leaving one case out "
                         "needs at least two")
    markers = {c: load_markers(campaign.case(c).markers) for c in cases}
    quiet = lambda text: None  # noqa: E731

    def fit(start, names, on, bounds, registrations=None):
        started = time.perf_counter()
        found = calibrate_campaign(campaign, start, names, on, solver, bounds=bounds,
                                   max_steps=FIT_STEPS, log=quiet,
                                   registrations=registrations)
        log(f"  fit of {', '.join(names)} to {len(on)} cases: {found.evaluations} "
            f"evaluations, {time.perf_counter() - started:.1f} s, mean square RMS "
            f"{np.mean(np.square(list(found.rms_mm_after.values()))):.1f} mm^2")
        if bar is not None:
            bar.update(1)
        return found

    def refit_held_out(start, names, bounds):
        rms = {}
        for case in cases:
            found = fit(start.model, names, [c for c in cases if c != case], bounds,
                        start.registrations)
            positions, _, converged = solver.tangents(campaign.case(case), found.model,
                                                      names)
            if not converged:
                raise RuntimeError(f"{case} does not converge when fitted to the others")
            rms[case] = smooth_shape_score(campaign_tube_surfaces(campaign, positions),
                                           markers[case],
                                           canopy_group=campaign.canopy_group).rms_mm
        return rms

    def scored(fitted, start, names, bounds):
        """``(held-out RMS {case: mm}, the fit to every case)``: ``fitted`` (or, when
        ``None``, a new fit from the fit ``start``'s model and registrations) and its cases
        scored when left out."""
        full = fit(start.model, names, cases, bounds, start.registrations) \
            if fitted is None else fitted
        if held_out == "refit":
            return refit_held_out(start, names, bounds), full
        return linearised_held_out(full, {n: bounds.get(n, value_bounds(n))
                                          for n in names}), full

    names, bounds = tuple(baseline), {}
    log(f"baseline: {', '.join(names)} fitted to {', '.join(cases)}")
    current = fit(model, names, cases, bounds)
    baseline_fit, added, steps, unseparated = current, [], [], []
    remaining = [e for e in candidates if not set(e.values) & set(names)]
    while remaining:
        current_held, _ = scored(current, current, names, bounds)
        current_square = float(np.mean(np.square(list(current_held.values()))))
        log(f"current model ({', '.join(names)}): held-out RMS "
            + ", ".join(f"{c} {r:.1f}" for c, r in current_held.items()) + " mm")
        ranking = [_rank(effect, current, current_square, names, bounds, scored,
                         len(remaining)) for effect in remaining]
        for entry in ranking:
            log(f"  {entry.effect.name}: held-out gain {entry.held_out_gain_mm2:.1f} mm^2, "
                f"BIC fall {entry.bic_fall:.1f}, p {entry.p_value:.2g}"
                + (f" (not added: {'; '.join(entry.reasons)})" if entry.reasons else ""))
        ranking.sort(key=lambda r: -r.held_out_gain_mm2 if math.isfinite(
            r.held_out_gain_mm2) else math.inf)
        steps.append((current_held, ranking))
        passing = [r for r in ranking if not r.reasons]
        if not passing:
            break
        best = passing[0]
        unseparated += [f"the cases cannot separate {best.effect.name} from "
                        f"{other.effect.name} (BIC falls {best.bic_fall:.1f} and "
                        f"{other.bic_fall:.1f})" for other in passing[1:]
                        if abs(other.bic_fall - best.bic_fall) < CLOSE_BIC]
        added.append(best.effect)
        names += best.effect.values
        bounds.update(best.effect.bounds)
        current = best.fit
        log(f"added {best.effect.name}: " + ", ".join(
            f"{n} = {v:.4g}" for n, v in zip(current.names, current.values)))
        remaining = [e for e in remaining if not set(e.values) & set(names)]
    unseparated += list(current.statements)
    if added:
        verdict = (f"missing: {', '.join(e.name for e in added)} (each lowers the error of "
                   "cases it was not fitted to and passes the likelihood-ratio and BIC "
                   "tests within its plausible range)")
    else:
        verdict = ("no candidate effect is missing: none lowers the error of cases it was "
                   "not fitted to and passes the likelihood-ratio and BIC tests within its "
                   "plausible range")
    return ShapeDiagnosis(baseline_fit, current, tuple(added), tuple(steps),
                          tuple(unseparated), verdict)


def _rank(effect, current, current_square, names, bounds, scored, in_play):
    """One candidate's :class:`ShapeCandidateRanking` (module docstring)."""
    trial_names = names + effect.values
    trial_bounds = {**bounds, **effect.bounds}
    try:
        rms, full = scored(None, current, trial_names, trial_bounds)
    except RuntimeError as error:
        return ShapeCandidateRanking(effect, {}, math.nan, math.nan, math.nan, math.nan, None,
                                (f"a fit failed: {error}",))
    gain = current_square - float(np.mean(np.square(list(rms.values()))))
    variance = full.residual_sum_squares_m2 / max(full.degrees_of_freedom, 1)
    q = len(effect.values)
    delta = (current.residual_sum_squares_m2 - full.residual_sum_squares_m2) / variance
    p_value = float(chi2.sf(max(delta, 0.0), q))
    bic_fall = delta - q * math.log(full.residual_count)
    reasons = []
    if not gain > 0:
        reasons.append("does not lower the error of cases it was not fitted to")
    if not p_value < ALPHA / in_play:
        reasons.append(f"likelihood ratio p = {p_value:.2g} >= {ALPHA}/{in_play}")
    if not bic_fall > BIC_THRESHOLD:
        reasons.append(f"the BIC falls by {bic_fall:.1f} <= {BIC_THRESHOLD}")
    for name, (low, high) in effect.bounds.items():
        value = float(full.values[full.names.index(name)])
        if on_bound(name, value, (low, high)):
            reasons.append(f"{name} = {value:.4g} on an edge of its plausible range "
                           f"{low}-{high}")
    if not full.converged:
        reasons.append(f"the fit did not converge ({full.message})")
    return ShapeCandidateRanking(effect, rms, gain, float(delta), p_value, float(bic_fall), full,
                            tuple(reasons))


def linearised_held_out(fit: CampaignCalibration, bounds: dict) -> dict:
    """``{case: smooth RMS [mm]}`` of each of ``fit``'s cases when its values are fitted to
    the others, from ``fit.least_squares`` alone: one Gauss-Newton step from the optimum on
    the other cases' rows (their registrations free), clipped to ``bounds`` (``{name: (low,
    high)}``), applied to the left-out case's residuals in the same linearisation, and that
    case re-registered (its six registration columns projected out)."""
    jacobian, residual, rows = fit.least_squares
    k = len(fit.names)
    theta = search_coordinates(fit.names, fit.values)
    low = search_coordinates(fit.names, [bounds[n][0] for n in fit.names])
    high = search_coordinates(fit.names, [bounds[n][1] for n in fit.names])
    rms = {}
    for c, (case, (first, last)) in enumerate(rows.items()):
        others = np.ones(len(residual), bool)
        others[first:last] = False
        free = np.ones(jacobian.shape[1], bool)
        free[k + 6 * c:k + 6 * c + 6] = False
        step = -np.linalg.lstsq(jacobian[others][:, free], residual[others], rcond=None)[0]
        step = np.clip(theta + step[:k], low, high) - theta
        own = jacobian[first:last]
        moved = residual[first:last] + own[:, :k] @ step
        registration = own[:, k + 6 * c:k + 6 * c + 6]
        moved = moved - registration @ np.linalg.lstsq(registration, moved, rcond=None)[0]
        rms[case] = 1e3 * float(np.sqrt(np.mean(np.square(moved))))
    return rms
