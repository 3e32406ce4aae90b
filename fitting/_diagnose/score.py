"""Statistics of candidate effects at a fitted model: the score test at the null, chi^2,
the likelihood-ratio p-value (with the boundary mixture), and how much of a candidate's
effect the model's fitted parameters can absorb (formulas and sources in
:mod:`fitting._diagnose.ranking`).

All work on the residuals and the Jacobian of a fit's last evaluation (``FitResult.residual``
and ``FitResult.jacobian``, every coordinate's column): no new evaluation, no compilation.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.stats

from .._calibrate.result import FitResult


def parameter_names(effect) -> tuple[str, ...]:
    """``effect.parameter`` names of an effect class's parameters, in order."""
    return tuple(f"{effect.name}.{p.name}" for p in effect.parameters)

@dataclasses.dataclass(frozen=True)
class ScoreTest:
    """Score test of freeing ``names`` (held at their null values in the fit).

    statistic: ``S`` (chi^2 units); dof: number of parameters; p_value; score: ``U``
    (per parameter, noise units per parameter unit).
    """

    names: tuple[str, ...]
    statistic: float
    dof: int
    p_value: float
    score: tuple[float, ...]


def _data_rows(result: FitResult) -> tuple[np.ndarray, np.ndarray]:
    """Residuals ``[n]`` and Jacobian ``[n, n_names]`` of the data rows (no prior rows)."""
    n_data = result.problem.batch.force.size
    return result.residual[:n_data], result.jacobian[:n_data]


def names_on_bounds(problem, vector, names) -> list[str]:
    """Those of ``names`` whose value in the full ``vector`` sits on a bound of the problem's
    box (lower or upper, to ``numpy.isclose``)."""
    index = [problem.names.index(name) for name in names]
    value = np.asarray(vector, float)[index]
    ends = np.isclose(value, problem.lower[index]) | np.isclose(value, problem.upper[index])
    return [name for name, end in zip(names, ends) if end]


def _lower_bound(problem, name: str) -> float:
    return float(problem.lower[problem.names.index(name)])


def score_test(result: FitResult, names) -> ScoreTest:
    """Score test for the coordinates ``names`` of ``result``'s problem, which the fit held
    fixed (at their null values). Uses the Jacobian of the fit's last evaluation: no new
    evaluation, no new compilation."""
    problem = result.problem
    names = tuple(names)
    index = [problem.names.index(name) for name in names]
    if any(i in problem.free_index for i in index):
        raise ValueError(f"{names}: a score test needs the coordinates held fixed in the fit")
    r, jac = _data_rows(result)
    j_b = jac[:, np.asarray(problem.free_index)]
    j_c = jac[:, np.asarray(index)]
    score = -j_c.T @ r
    projection = j_c.T @ j_b @ np.linalg.pinv(j_b.T @ j_b, rcond=1e-12, hermitian=True)
    information = j_c.T @ j_c - projection @ (j_b.T @ j_c)
    statistic = float(score @ np.linalg.pinv(information, rcond=1e-12, hermitian=True) @ score)
    dof = len(names)
    lower = np.array([_lower_bound(problem, name) for name in names])
    at_bound = np.isclose(result.vector[np.asarray(index)], lower)
    if dof == 1 and at_bound[0]:
        if score[0] <= 0:
            statistic = 0.0
        p_value = 0.5 * float(scipy.stats.chi2.sf(statistic, 1)) if statistic > 0 else 1.0
    else:
        p_value = float(scipy.stats.chi2.sf(statistic, dof))
    return ScoreTest(names, max(statistic, 0.0), dof, p_value, tuple(float(u) for u in score))


# --------------------------------------------------------------------------------------------
# Goodness of a model: chi^2, BIC, cross-validation
# --------------------------------------------------------------------------------------------


def chi2(result: FitResult) -> float:
    """Weighted chi^2 of the data in noise units (the prior rows excluded)."""
    r, _ = _data_rows(result)
    return float(r @ r)


def point_count(result: FitResult) -> int:
    return int(np.sum(result.problem.batch.weight > 0))


def dispersion(result: FitResult) -> float:
    """``chi^2 / dof`` of a fit (noise units; ``dof`` = points - fitted coordinates): 1 when
    its residuals are the noise, larger when the model still misses something (or the
    noise is underestimated)."""
    dof = max(point_count(result) - len(result.problem.free_index), 1)
    return chi2(result) / dof


def likelihood_ratio_p_value(statistic: float, dof: int, at_bound: int) -> float:
    """p-value of the likelihood-ratio statistic ``LR = chi^2_null - chi^2_refit`` (noise
    units) for freeing ``dof`` coordinates of which ``at_bound`` have their null value on a
    bound of the feasible set.

    A parameter whose null is on the boundary makes the limit distribution a mixture (Chernoff,
    Ann. Math. Stat. 25, 1954; Self & Liang, JASA 82, 1987): for one such parameter
    ``0.5 chi^2_0 + 0.5 chi^2_1``; for ``b`` of them (taken as orthogonal) and ``dof - b``
    interior ones, ``sum_k C(b, k) 2^-b chi^2_{dof - b + k}`` (``chi^2_0`` a point mass at 0).
    """
    if not 0 <= at_bound <= dof:
        raise ValueError(f"at_bound must be within 0..{dof}, got {at_bound}")
    statistic = max(float(statistic), 0.0)
    interior = dof - at_bound
    total = 0.0
    for k in range(at_bound + 1):
        weight = math.comb(at_bound, k) / 2**at_bound
        df = interior + k
        tail = (1.0 if statistic <= 0 else 0.0) if df == 0 else float(
            scipy.stats.chi2.sf(statistic, df))
        total += weight * tail
    return min(total, 1.0)


# --------------------------------------------------------------------------------------------
# Candidates and their ranking


def _orthonormal(matrix: np.ndarray, rcond: float = 1e-9) -> np.ndarray:
    if matrix.size == 0:
        return matrix
    u, s, _ = np.linalg.svd(matrix, full_matrices=False)
    keep = s > rcond * max(float(s[0]), 1e-300) if s.size else s > 0
    return u[:, keep]


def absorbed_free_effects(result: FitResult, candidates) -> dict[str, np.ndarray]:
    """Per candidate (held at its null in ``result``): ``(I - P_b) J_c``, the part of its
    effect on the curves that refitting the current parameters cannot reproduce."""
    _, jac = _data_rows(result)
    q_b = _orthonormal(jac[:, np.asarray(result.problem.free_index)])
    out = {}
    for effect in candidates:
        index = [result.problem.names.index(n) for n in parameter_names(effect)]
        j_c = jac[:, index]
        out[effect.name] = (j_c - q_b @ (q_b.T @ j_c), j_c)
    return out


def _share(residual_part, whole) -> float:
    norm = float(np.sum(whole**2))
    return float(np.sum(residual_part**2) / norm) if norm > 0 else 0.0


def canonical_correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Largest canonical correlation (cosine of the smallest principal angle) of the column
    spaces of ``a`` and ``b``."""
    qa, qb = _orthonormal(a), _orthonormal(b)
    if qa.shape[1] == 0 or qb.shape[1] == 0:
        return 0.0
    return float(np.linalg.svd(qa.T @ qb, compute_uv=False)[0])
