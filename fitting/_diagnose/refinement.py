"""Pivot refinement: when no candidate is significant and the residuals are still
systematic, the bending law's resolution is the next suspect.

With one pivot per regime, the law's wrinkled branch is one cubic Hermite piece from the
wrinkling onset to the collapse pivot, and its end slope follows from the collapsed-regime
pivot, which bench curves rarely reach, so it is held at the physics guess. A truth whose
moment approaches its collapse value slowly (the tension-field tube: ``M_c - M ~
(kappa_w / kappa)^(2/3)``, docs/physics.md, section 2.3) then leaves a systematic misfit that
no physical effect explains. The refinement adds one pivot to the unwrinkled and one to the
wrinkled regime (the collapsed regime's pivots are the ones bench curves do not determine),
refits the current model's effects with the finer law from the current optimum, every
pivot coordinate free, holds what the data do not determine where that fit left it, as the
baseline does, and keeps the finer law when its BIC, in
units of its residual scatter as in the ranking, is lower by more than ``bic_threshold``; the
BIC counts every coordinate of that first fit (the held ones moved in it).

The finer layout has its own compiled model (the pivot count changes the arrays); the
candidates are compiled in at their null values as for the baseline, so the ranking goes on
against the refined model. The two layouts are not nested (the knot slopes are recomputed),
so the comparison is by BIC (Schwarz 1978), which does not need nesting, and no
likelihood-ratio test is claimed for it.
"""

from __future__ import annotations

import dataclasses
import math

import jax.numpy as jnp
import numpy as np

from .._bench.scaling import PivotScaling
from .._calibrate.fit import fit_problem
from .._calibrate.problem import FitError, make_problem
from .._calibrate.result import FitResult
from .score import chi2, parameter_names
from .selection import bic, hold_undetermined_where_left

#: At most this many refinements in one diagnosis, each one more unwrinkled and wrinkled
#: pivot than the last: (1,1,1) -> (2,2,1) -> (3,3,1). Against the tension-field truth
#: of the diagnosis study, a single curve at 0.12 % force noise (design_0_0084 of
#: ``experiments/diagnosis_study.py``) leaves RMSE 18x, 1.5x and 0.9x its noise floor.
PIVOT_REFINEMENTS = 2


def refined_scaling(scaling: PivotScaling) -> PivotScaling:
    """One more pivot in the unwrinkled and the wrinkled regime."""
    unwrinkled, wrinkled, collapsed = scaling.pivots_per_regime
    return dataclasses.replace(scaling, pivots_per_regime=(unwrinkled + 1, wrinkled + 1,
                                                           collapsed))


def refined_start(current: FitResult, problem) -> np.ndarray:
    """The refined problem's vector that follows ``current``'s law: the last increment of
    the unwrinkled and of the wrinkled regime is split at its middle curvature (at the
    reference specimen), the new pivot's moment read off the current law there; both halves
    keep the split increment's exponents. Effect parameters are copied by name."""
    coarse, fine = current.problem.scaling, problem.scaling
    pivot_count = coarse.pivot_count
    vector = np.asarray(current.vector, float)
    pivots = vector[:2 * pivot_count * (1 + len(coarse.exponents))]
    (log_ak, *exp_k), (log_am, *exp_m) = coarse._split(pivots)
    p_ref, r_ref = current.problem.reference
    law = coarse.law(jnp.asarray(pivots), p_ref, r_ref)
    curvatures = np.cumsum(np.exp(log_ak))
    ends = np.cumsum(coarse.pivots_per_regime)[:2] - 1  # last pivot of regimes 1 and 2
    new_k, new_m, new_exp_k, new_exp_m = [], [], [], []
    for i in range(pivot_count):
        if i in ends:
            before = curvatures[i - 1] if i > 0 else 0.0
            middle = 0.5 * (before + curvatures[i])
            moment_before = float(law.moment(before, p_ref, r_ref)) if i > 0 else 0.0
            moment_middle = float(law.moment(middle, p_ref, r_ref))
            moment_end = moment_before + math.exp(log_am[i])
            share = np.clip((moment_middle - moment_before) / (moment_end - moment_before),
                            0.05, 0.95)
            new_k += [log_ak[i] + math.log(0.5)] * 2
            new_m += [log_am[i] + math.log(share), log_am[i] + math.log(1.0 - share)]
            new_exp_k += [[e[i] for e in exp_k]] * 2
            new_exp_m += [[e[i] for e in exp_m]] * 2
        else:
            new_k.append(log_ak[i])
            new_m.append(log_am[i])
            new_exp_k.append([e[i] for e in exp_k])
            new_exp_m.append([e[i] for e in exp_m])
    blocks = []
    for logs, exps in ((new_k, new_exp_k), (new_m, new_exp_m)):
        blocks.append(np.asarray(logs))
        blocks += [np.asarray([e[j] for e in exps]) for j in range(len(fine.exponents))]
    start = np.array(problem.base, float)
    start[:sum(b.size for b in blocks)] = np.concatenate(blocks)
    for name, value in zip(current.problem.names, vector):
        if name in current.problem.effect_names:
            start[problem.names.index(name)] = value
    return start


def split_parents(scaling: PivotScaling) -> list[int]:
    """For each pivot of :func:`refined_scaling`'s law, the pivot of ``scaling``'s law it
    comes from (:func:`refined_start` splits the last pivot of the unwrinkled and of the
    wrinkled regime in two)."""
    ends = np.cumsum(scaling.pivots_per_regime)[:2] - 1
    return [i for i in range(scaling.pivot_count) for _ in range(2 if i in ends else 1)]


def refined_held(current: FitResult, scaling: PivotScaling) -> list[str]:
    """The refined law's pivot coordinates (names of ``scaling``, the refined layout) whose
    parent coordinate (:func:`split_parents`) ``current`` holds: the data did not determine
    it (a pressure exponent at a single value of ``p r^3``, the collapsed pivot), and
    splitting its pivot does not make them determine it. They stay where
    :func:`refined_start` puts them (the parent's value)."""
    coarse = current.problem.scaling
    free = set(current.problem.free_names)
    parents = split_parents(coarse)
    held = []
    for name in scaling.names():
        coordinate, rest = name.split("[", 1)
        index, kind = rest.split("].", 1)
        parent = f"{coordinate}[{parents[int(index) - 1] + 1}].{kind}"
        if parent in coarse.names() and parent not in free:
            held.append(name)
    return held


def refine_pivots(current: FitResult, in_model, by_name, data, rig, fit_options, candidates,
                  bic_threshold: float, n_points: int):
    """Refit ``current`` (effects ``in_model`` free) with :func:`refined_scaling`'s law, from
    :func:`refined_start`; coordinates the refit leaves undetermined are held where it left
    them and the rest refitted (as the diagnosis' baseline). Returns ``(refit or None, held
    names, words)``: the refit when its BIC,
    in units of its residual scatter, is lower than ``current``'s by more than
    ``bic_threshold``."""
    scaling = refined_scaling(current.problem.scaling)
    layout = ",".join(str(n) for n in scaling.pivots_per_regime)
    effect_names = [n for e in in_model for n in parameter_names(by_name[e])]
    kept_held = refined_held(current, scaling)
    pivots = [name for name in scaling.names() if name not in kept_held]
    if n_points <= 2 * (len(pivots) + len(effect_names)):
        return None, [], [f"The law refined to pivots ({layout}) was not tried: "
                          f"{len(pivots) + len(effect_names)} coordinates for {n_points} "
                          "points."]
    problem = make_problem(data, scaling, rig, fit_options, effects=candidates)
    start = refined_start(current, problem)
    try:
        refit = fit_problem(problem.with_free(pivots + effect_names, start), fit_options)
        # As for the baseline: what the data do not determine is held where the fit left it
        # (resetting it to the start would undo the part of the fit it carried).
        refit, held = hold_undetermined_where_left(refit, fit_options)
    except FitError as error:
        return None, [], [f"The law refined to pivots ({layout}) could not be fitted: {error}."]
    # The held coordinates moved in the first fit, so all of its coordinates are counted.
    used = len(pivots) + len(effect_names)
    c = max(1.0, chi2(refit) / max(n_points - used, 1))
    gain = bic(current, n_points, c) - (chi2(refit) / c + used * math.log(n_points))
    summary = (f"the law refined to pivots ({layout}) per regime, with "
               f"{', '.join(in_model) or 'no effect'}: RMSE {current.rmse:.4g} -> "
               f"{refit.rmse:.4g} N, BIC {-gain:+.1f} in units of its residual scatter "
               f"(c = {c:.3g}; {used} coordinates fitted, {len(held)} of them then held, against "
               f"{len(current.problem.free_index)})")
    if gain > bic_threshold:
        return refit, kept_held + held, [
            "No candidate is significant and the residuals are still systematic: "
            f"{summary}; kept (the BIC falls by more than {bic_threshold:g})."]
    return None, [], ["No candidate is significant and the residuals are still systematic; "
                  f"{summary}; not kept (the BIC must fall by more than {bic_threshold:g}), "
                  "so the misfit is not the law's resolution."]


__all__ = ["PIVOT_REFINEMENTS", "refine_pivots", "refined_held", "refined_scaling",
           "refined_start", "split_parents"]
