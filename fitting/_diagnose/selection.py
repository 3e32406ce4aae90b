"""Refits of the diagnosis that do not stall at the null, plausible sizes, and the backward /
swap step after each addition (rules and sources in :mod:`fitting._diagnose.ranking`)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.linalg

from .._bench.scaling import COORDINATES
from .._calibrate.fit import fit_problem
from .._calibrate.outcome import FitOutcome
from .._calibrate.problem import FitError
from .._calibrate.result import FitResult
from .score import (
    chi2,
    dispersion,
    likelihood_ratio_p_value,
    names_on_bounds,
    parameter_names,
)

#: A competitor replaces an earlier addition when it lowers the BIC by more than this
#: ("positive" evidence on the scale of Kass & Raftery 1995; it keeps near-ties from swapping).
SWAP_BIC = 2.0
#: A competitor of an earlier step is tried in the addition's place only when, at that
#: step, its own refit lowered the BIC by at least this share of the addition's drop: one
#: that explained less than half of it alone would have to explain the rest from nothing
#: (each try is a whole refit).
SWAP_SHORTLIST = 0.5


def bound_count(problem, names) -> int:
    """How many of ``names`` have their null value (their value in ``problem.base``) on a
    bound: those make the likelihood-ratio test a boundary mixture."""
    return len(names_on_bounds(problem, problem.base, names))


def _ended_on_a_bound(problem, names, refit) -> bool:
    """Whether the refit failed or left some parameter of ``names`` on a bound: still on a
    null that is a bound (where a projected step may have stalled), or pushed to the edge of
    its box (a basin other than the physical one)."""
    return refit is None or bool(names_on_bounds(problem, refit.vector, names))


def refit_candidate(problem, names, effect, fit_options):
    """The refit with ``names`` freed, from the null and, unless that refit ended inside the
    box at least as far from the null as the effect's typical size, again from the typical
    size; the better of the two.

    Why a second start: a refit from the null can stop short, in a local minimum between the
    null and the physical basin, or on a null that is a bound (a projected step can stall
    there: the first-order direction may point out of the feasible set while the refit, with
    the pivots moving along, finds a large improvement inside it); or it can end at the far
    edge of the parameter's box (a basin other than the physical one, e.g. a radius exponent
    at +4 where the tension-field tube has -3). From the null alone, a stall cannot be told
    from a small effect (design_0_0085 of the diagnosis study: shear stalls at 3.5e-6 m/N
    with chi^2 34,117 from the null and reaches 2.6e-4 m/N, the hidden size, with chi^2 407
    from the typical 1e-4 m/N). A refit that went past the typical size is not repeated: the
    typical start lies on its way. The second start ends as soon as the parameters whose null
    is a bound are all back on it, held there by the active set
    (``FitOptions.stop_on_bound``): it found no basin away from the null, and what it would
    still gain there, the candidate at its null, would not be the candidate's; such a start
    is not kept. Returns ``(refit or None, failure words)``."""
    typical = np.array(problem.base, float)
    for name, parameter in zip(names, effect.parameters):
        i = problem.names.index(name)
        typical[i] = float(np.clip(parameter.typical, problem.lower[i], problem.upper[i]))
    on_null = tuple(name for name in names if bound_count(problem, (name,)))
    second = (dataclasses.replace(fit_options, stop_on_bound=on_null) if on_null
              else fit_options)
    best, failure = None, ""
    for start, options in ((problem.base, fit_options), (typical, second)):
        try:
            refit = fit_problem(problem.with_free(problem.free_names, start), options)
        except FitError as error:  # reported as a failed candidate, never dropped silently
            failure = str(error)
            refit = None
        back = refit is not None and refit.convergence.message == FitOutcome[
            FitOutcome.back_on_bound]
        if refit is not None and not back and (best is None or chi2(refit) < chi2(best)):
            best = refit
        if not _ended_on_a_bound(problem, names, best) and _past_typical(problem, names,
                                                                       typical, best):
            break
    return best, failure


def _past_typical(problem, names, typical, refit) -> bool:
    """Whether every parameter of ``names`` ended at least as far from its null as the
    typical size (on the same side): the typical start then lies on the refit's way."""
    for name in names:
        i = problem.names.index(name)
        null, value, start = problem.base[i], refit.vector[i], typical[i]
        if (value - null) * np.sign(start - null) < abs(start - null):
            return False
    return True


def implausible_words(effect, names, estimates) -> list[str]:
    """Sentences for the parameters whose fitted size is outside the effect's plausible
    range (:class:`fitting.EffectParameter` ``plausible``)."""
    words = []
    for name, parameter in zip(names, effect.parameters):
        if parameter.plausible is None:
            continue
        low, high = parameter.plausible
        value = estimates[name]
        if not low <= value <= high:
            words.append(
                f"{effect.name} explains it only at {parameter.name} = {value:.3g} "
                f"{parameter.unit}, outside the plausible {low:.3g}-{high:.3g} "
                f"{parameter.unit} ({parameter.plausible_source}); something else is likely "
                "missing")
    return words


def bic(result: FitResult, n_points: int, c: float = 1.0) -> float:
    """``chi^2 / c + k ln n`` (Schwarz 1978) of a fit with ``k`` fitted coordinates, chi^2 in
    units of ``c`` times the noise variance (the ranking's dispersion)."""
    return chi2(result) / c + len(result.problem.free_index) * math.log(n_points)


def _without(current: FitResult, drop, add, held, polish):
    """``current`` refitted with the effect ``drop`` back at its null values and the effect
    ``add`` (or None) freed (a second start when the first ends on a bound, as in the
    ranking); None if the refit failed."""
    problem = current.problem
    vector = np.array(current.vector, float)
    dropped = parameter_names(drop)
    for name in dropped:
        vector[problem.names.index(name)] = held[name]
    free = [name for name in problem.free_names if name not in dropped]
    if add is None:
        try:
            return fit_problem(problem.with_free(free, vector), polish)
        except FitError:
            return None
    names = parameter_names(add)
    refit, _ = refit_candidate(problem.with_free(free + list(names), vector), names, add,
                               polish)
    return refit


def backward_step(current, in_model, steps, best, by_name, held, options, polish, n_points):
    """After adding ``best`` (a ranking row): is each earlier addition still needed
    (likelihood ratio and BIC of keeping it, given the rest), and would a competitor of its
    own step (significant there, plausible, not in the model) now explain the data better in
    its place (BIC lower by more than :data:`SWAP_BIC`)? ``in_model`` (names, in order) is
    updated in place. Evidence in units of the current model's residual scatter when that
    exceeds the noise (``c``, as in the ranking). Returns ``(model, removed names, words)``."""
    words, removed = [], []
    alpha = options.alpha / max(len(by_name), 1)
    c = max(1.0, dispersion(current))
    for step in steps:
        name = step.added
        if name not in in_model or name == best.effect:
            continue
        effect = by_name[name]
        reduced = _without(current, effect, None, held, polish)
        if reduced is None:
            continue
        q = len(effect.parameters)
        ratio = max(chi2(reduced) - chi2(current), 0.0) / c
        bounded = sum(bool(np.isclose(held[n], current.problem.lower[
            current.problem.names.index(n)])) for n in parameter_names(effect))
        p_value = likelihood_ratio_p_value(ratio, q, bounded)
        keep_gain = ratio - q * math.log(n_points)
        if not (p_value < alpha and keep_gain > options.bic_threshold):
            words.append(
                f"{name} (added at an earlier step) is removed: once {best.effect} is in, "
                f"keeping it lowers chi^2 by only {ratio:.3g} (likelihood-ratio p = "
                f"{p_value:.2g}, BIC gain {keep_gain:.1f}).")
            removed.append(name)
            in_model.remove(name)
            current = reduced
            continue
        shortlist = SWAP_SHORTLIST * step.candidates[0].delta_bic
        rivals = [row for row in step.candidates
                  if row.significant and row.effect != name and row.effect not in in_model
                  and row.effect not in removed and row.delta_bic <= shortlist]
        for rival in rivals:
            swapped = _without(current, effect, by_name[rival.effect], held, polish)
            if swapped is None:
                continue
            rival_names = parameter_names(by_name[rival.effect])
            estimates = {n: float(swapped.vector[swapped.problem.names.index(n)])
                         for n in rival_names}
            plausible = not implausible_words(by_name[rival.effect], rival_names, estimates)
            gain = bic(current, n_points, c) - bic(swapped, n_points, c)
            if plausible and gain > SWAP_BIC:
                words.append(
                    f"{name} (added at an earlier step) is swapped for {rival.effect}: with "
                    f"{best.effect} in the model, {rival.effect} in its place lowers the BIC "
                    f"by {gain:.1f} more.")
                removed.append(name)
                in_model[in_model.index(name)] = rival.effect
                current = swapped
                break
            words.append(f"{name} is kept: {rival.effect} in its place does not do better "
                         f"(BIC {-gain:+.1f}" + ("" if plausible else ", implausible size")
                         + ").")
    return current, removed, words


#: :func:`settle` refits the current model until a refit lowers chi^2 (noise units) by less
#: than this, in at most :data:`SETTLE_ROUNDS` refits.
SETTLED_CHI2 = 1.0
SETTLE_ROUNDS = 3


def settle(current: FitResult, fit_options) -> FitResult:
    """``current`` refitted (the same free coordinates, from where it is) until a refit gains
    less than :data:`SETTLED_CHI2`: the candidates are ranked against the current model's
    optimum. Each candidate's refit starts from the current model and runs the refit's
    iterations; where the current model had not reached its own optimum (its fit ended at
    the iteration cap, or crawled along a flat valley), every candidate's refit gained the
    same chi^2 by finishing that convergence, effect or not, and a candidate that the
    pivots absorb entirely could be named (the diagnosis study's design_0_0084, nothing
    hidden: shear, reinforcement, clamp compliance and self-weight each gained 16-19 noise
    units with 0 % of their effect unabsorbed, and reinforcement was named)."""
    for _ in range(SETTLE_ROUNDS):
        try:
            refit = fit_problem(current.problem.with_free(current.problem.free_names,
                                                          current.vector), fit_options)
        except FitError:
            break
        gain = chi2(current) - chi2(refit)
        if gain > 0.0:
            current = refit
        if gain < SETTLED_CHI2:
            break
    return current


#: A coordinate is held as undetermined by :func:`least_determined` when its column adds less
#: than this fraction of the largest (unit-scaled) column's norm to the span of the columns
#: before it (pivoted QR): its information is below 1e-8 of the best determined one's.
UNDETERMINED_PIVOT = 1e-4
#: A column whose norm is below this fraction of the largest column's is rounding error, not
#: information: a pressure exponent when every curve has the same ``p r^3``, whose column
#: ``y log(p r^3 / p_ref r_ref^3)`` is zero but for the last bits of the logarithms.
#: Unit scaling would blow it up to a column as good as any, parallel to its pivot's
#: ``log a`` column, and the QR could then keep the exponent and hold the ``log a``: the law
#: could no longer move (the diagnosis study's design_0_0070 kept its first guess, 43x the
#: noise floor). A real exponent column is ``|log(s / s_ref)|`` (0.01 or more) times its
#: ``log a`` column, far above this.
ROUNDING_COLUMN = 1e-12


def least_determined(result: FitResult) -> list[str]:
    """The free coordinates the data determine least, one per direction they do not see:
    the trailing pivots of a rank-revealing QR factorisation (Businger & Golub 1965) of the
    unit-scaled Jacobian columns, past the first whose pivot falls below
    :data:`UNDETERMINED_PIVOT` of the largest. Used when every coordinate's standard error
    is flagged: a few undetermined directions (every pressure exponent at a single
    pressure, say) inflate the errors of all the coordinates they mix with, and holding
    them all would leave nothing to fit."""
    jac = result.jacobian[:, np.asarray(result.problem.free_index)]
    norms = np.linalg.norm(jac, axis=0)
    rounding = norms <= ROUNDING_COLUMN * max(float(norms.max(initial=0.0)), 1e-300)
    kept = np.flatnonzero(~rounding)
    if kept.size == 0:
        return list(result.problem.free_names)
    _, r, pivots = scipy.linalg.qr(jac[:, kept] / norms[kept], mode="economic",
                                   pivoting=True)
    size = np.abs(np.diag(r))
    rank = int(np.sum(size > UNDETERMINED_PIVOT * max(float(size[0]), 1e-300)))
    undetermined = set(kept[pivots[rank:]].tolist()) | set(np.flatnonzero(rounding).tolist())
    return [result.problem.free_names[k] for k in sorted(undetermined)]


def _flagged(result: FitResult) -> list[str]:
    """The free coordinates ``result`` leaves undetermined (infinite standard error); when
    every one is flagged, only the least determined ones (:func:`least_determined`)."""
    held = [name for name, se in zip(result.problem.free_names, result.free_standard_errors)
            if not math.isfinite(se)]
    return least_determined(result) if len(held) == len(result.problem.free_names) else held


def _is_exponent(name: str) -> bool:
    """Whether ``name`` is a pivot exponent of the law (``kappa[2].B``, ``M[1].C``)."""
    return name.split("[", 1)[0] in COORDINATES and not name.endswith(".A")


def hold_undetermined_where_left(result: FitResult, fit_options):
    """Hold the coordinates ``result`` leaves undetermined (:func:`_flagged`) where it left
    them and refit the rest from there (the baseline and the refined law do this: they
    would only drift along them). Exponents first: where exponents and increments (``log
    a``) are flagged together, the flagged exponents are held and the increments looked at
    again after that refit. An exponent the data barely determine (few values of ``p r^3``)
    trades with its pivot's increment and inflates its error too; holding both froze the
    wrinkled pivot where the first fit had crawled to (the diagnosis study's
    design_0_0053: one pressure, two radii, 10 of 12 coordinates held, final RMSE 3.4x the
    noise floor). Returns ``(model, held names)``."""
    held = _flagged(result)
    exponents = [name for name in held if _is_exponent(name)]
    if exponents and len(exponents) < len(held):
        kept = [name for name in result.problem.free_names if name not in exponents]
        result = fit_problem(result.problem.with_free(kept, result.vector), fit_options)
        held = exponents + _flagged(result)
    if set(held) & set(result.problem.free_names):
        kept = [name for name in result.problem.free_names if name not in held]
        result = fit_problem(result.problem.with_free(kept, result.vector), fit_options)
    return result, held


def release_held(current: FitResult, held_since_baseline, polish, n_points):
    """Free again the coordinates held since the baseline (``held_since_baseline``: the
    baseline left them undetermined) that the current model determines.

    An addition can make a coordinate determinable that the baseline could not see: with the
    radius exponents freed (``radius_scaling``), the pressure exponents of the pivots are no
    longer tied to the radius; with shear taking its share of the deflection, the bending
    law's wrinkled pivots move. The refit from ``current`` with every held coordinate freed
    says which now have a finite standard error; those are kept free (refitted alone if some
    stay undetermined) when the BIC, in units of the refit's residual scatter as in the
    ranking, falls. Returns ``(model, released names, words)``; ``current`` unchanged (and
    no names) when none is determined or freeing them does not pay."""
    names = [n for n in held_since_baseline if n not in current.problem.free_names]
    if not names:
        return current, [], []
    problem = current.problem
    free = list(problem.free_names)
    try:
        trial = fit_problem(problem.with_free(free + names, current.vector), polish)
        errors = dict(zip(trial.problem.free_names, trial.free_standard_errors))
        determined = [n for n in names if math.isfinite(errors[n])]
        if determined and len(determined) < len(names):
            vector = np.array(trial.vector, float)
            for name in names:
                if name not in determined:
                    vector[problem.names.index(name)] = current.vector[problem.names.index(name)]
            trial = fit_problem(problem.with_free(free + determined, vector), polish)
            errors = dict(zip(trial.problem.free_names, trial.free_standard_errors))
            determined = [n for n in determined if math.isfinite(errors[n])]
            if len(determined) < len(trial.problem.free_names) - len(free):
                return current, [], []  # the second refit lost one again: keep them held
    except FitError:
        return current, [], []
    if not determined:
        return current, [], []
    c = max(1.0, dispersion(trial))
    gain = bic(current, n_points, c) - bic(trial, n_points, c)
    if gain <= 0.0:
        return current, [], [
            f"{', '.join(determined)} (held since the baseline): determined by this model, "
            f"but freeing {'them' if len(determined) > 1 else 'it'} does not pay (BIC "
            f"{-gain:+.1f}): held as before."]
    return trial, determined, [
        f"{', '.join(determined)} (held since the baseline, which did not determine "
        f"{'them' if len(determined) > 1 else 'it'}): determined by this model and freed "
        f"again: RMSE {current.rmse:.4g} -> "
        f"{trial.rmse:.4g} N, BIC {-gain:+.1f}."]
