"""Which effect is missing: score (Lagrange-multiplier) tests at the null.

For a fit in which a candidate's parameters are held at their null values, the score test
asks whether freeing them would lower the loss by more than noise, without refitting
(Rao 1948; e.g. Boos & Stefanski, *Essential Statistical Inference*, 2013, section 6.4).
With ``r`` the residuals in noise units, ``J_b`` the Jacobian columns of the fitted
coordinates and ``J_c`` those of the candidate's::

    U = -J_c^T r                                   (score: loss decrease per unit change)
    I = J_c^T J_c - J_c^T J_b (J_b^T J_b)^+ J_b^T J_c   (efficient information)
    S = U^T I^+ U  ~  chi^2_q under the null

Effects are bounded at their null (a stiffness, a compliance, a mass cannot be negative),
so for a single parameter the test is one-sided: ``S = 0`` when the score points out of the
feasible side, and the p-value is half the chi^2_1 tail (Self & Liang 1987).

This module is the first part of the diagnosis of issue 4; the ranking by refits, ΔBIC and
cross-validation, the iterative additions and ``jaxtube diagnose`` build on it.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np
import scipy.stats

from ._calibrate import _residuals_and_jacobian
from ._result import FitResult


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


def score_test(result: FitResult, names) -> ScoreTest:
    """Score test for the coordinates ``names`` of ``result``'s problem, which the fit held
    fixed (at their null values). Uses the fit's compiled model: no new compilation."""
    problem = result.problem
    names = tuple(names)
    index = [problem.names.index(name) for name in names]
    if any(i in problem.free_index for i in index):
        raise ValueError(f"{names}: a score test needs the coordinates held fixed in the fit")
    r, jac, _ = _residuals_and_jacobian(jnp.asarray(result.vector), *problem.residual_args(),
                                        **problem.static())
    n_data = problem.batch.force.size
    r = np.asarray(r)[:n_data]
    jac = np.asarray(jac)[:n_data]
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


def _lower_bound(problem, name: str) -> float:
    for effect in problem.effects:
        for parameter in effect.parameters:
            if name == f"{effect.name}.{parameter.name}":
                return parameter.lower
    return -np.inf
