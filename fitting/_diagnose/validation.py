"""Cross-validation of a fitted model over blocks of points within curves, with a check that
every fold's refit is determined by the points it keeps (rules in
:mod:`fitting._diagnose.ranking`).

Leaving whole curves out fails with few curves: with four curves at two pressures and two
radii, a held-out curve takes with it the only information on some pivot, and the refit
without it is undetermined (its error says nothing about the model). Blocks within curves
keep every specimen in every fold.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .._calibrate.result import FitResult

#: Folds of the blocked cross-validation, and the largest leverage a held-out fold may have
#: (largest eigenvalue of its block of the hat matrix): above it the remaining rows carry
#: less than a tenth of the information on some direction, so the fold's refit is all but
#: undetermined and its case-deletion estimate, which divides by ``1 - leverage``, is not to
#: be trusted. Holding out the large-deflection quarter of a curve reaches about 0.7 on a
#: well-posed design.
CV_FOLDS = 4
CV_LEVERAGE_LIMIT = 0.9
#: The cross-validation guards against overfitting: it vetoes a candidate when the
#: candidate's held-out squared errors exceed the current model's by more than this many
#: standard errors of their paired mean difference (one-sided, about 2.3 %). A rise within
#: its own scatter is not evidence of overfitting (the likelihood ratio decides).
CV_RISE_Z = 2.0


@dataclasses.dataclass(frozen=True)
class CrossValidation:
    """Blocked cross-validated RMSE [N] of a fit (``rmse_N``; nan when not ``valid``), the
    folds' ``largest_leverage``, the number of ``folds``, in ``words`` why it is not valid
    (empty when it is), and ``held_out``: every point's held-out residual in noise units
    ``[C * P]`` (0 for padding)."""

    rmse_N: float
    valid: bool
    largest_leverage: float
    folds: int
    words: str
    held_out: np.ndarray = dataclasses.field(default=None, repr=False, compare=False)

    def rise_z(self, other: CrossValidation) -> float:
        """How many standard errors this fit's held-out squared errors exceed ``other``'s
        (same data, same folds): the paired mean difference over the points over its
        standard error (positive: this one predicts the held-out points worse)."""
        if not (self.valid and other.valid):
            return math.nan
        d = self.held_out**2 - other.held_out**2
        d = d[(self.held_out != 0) | (other.held_out != 0)]
        se = float(np.std(d, ddof=1)) / math.sqrt(d.size) if d.size > 1 else 0.0
        return float(np.mean(d)) / se if se > 0 else 0.0


def fold_of_points(problem, folds: int = CV_FOLDS) -> np.ndarray:
    """``[C, P]`` fold index of every point (-1: padding): each curve, ordered by
    deflection, is cut into ``folds`` contiguous blocks, and fold ``k`` holds out block
    ``(k + c) mod folds`` of curve ``c``: every fold keeps every specimen, and no fold
    removes the same stretch (e.g. all the large deflections) of every curve."""
    deflection = np.abs(problem.batch.deflection)
    weight = problem.batch.weight
    out = np.full(deflection.shape, -1)
    for c in range(deflection.shape[0]):
        real = np.flatnonzero(weight[c] > 0)
        order = real[np.argsort(deflection[c, real], kind="stable")]
        block = (np.arange(order.size) * folds) // max(order.size, 1)
        out[c, order] = (block - c) % folds
    return out


def blocked_cross_validation(result: FitResult, folds: int = CV_FOLDS) -> CrossValidation:
    """Cross-validated RMSE over blocks of points within curves (:func:`fold_of_points`).

    Each fold's refit is the case-deletion estimate from the full-data optimum, exact for the
    model linearised there: the held-out residuals are ``(I - H_ff)^-1 r_f`` with ``H`` the
    hat matrix of the fitted (not bound-held) coordinates (Cook & Weisberg, *Residuals and
    Influence in Regression*, 1982, section 3.6). It is trusted only when every fold's
    largest leverage is below :data:`CV_LEVERAGE_LIMIT`; otherwise ``rmse_N`` is nan and
    ``words`` say why (the decision then does without it)."""
    problem = result.problem
    free = np.asarray(problem.free_index)
    lower, upper = problem.free_bounds
    x = result.free_values
    movable = ~(np.isclose(x, lower) | np.isclose(x, upper))
    jac = result.jacobian[:, free][:, movable]
    r = result.residual
    n_data = problem.batch.force.size
    fold = np.concatenate([fold_of_points(problem, folds).reshape(-1),
                           np.full(r.size - n_data, -1)])
    u, s, _ = np.linalg.svd(jac, full_matrices=False)
    u = u[:, s > 1e-10 * max(float(s[0]) if s.size else 0.0, 1e-300)]
    total, largest = 0.0, 0.0
    held_out = np.zeros(n_data)
    for k in range(folds):
        rows = fold == k
        if not rows.any():
            continue
        u_f = u[rows]
        hat = u_f @ u_f.T
        leverage = float(np.linalg.eigvalsh(hat)[-1]) if hat.size else 0.0
        largest = max(largest, leverage)
        if leverage < 1.0 - 1e-9:
            held = np.linalg.solve(np.eye(hat.shape[0]) - hat, r[rows])
            total += float(held @ held)
            held_out[rows[:n_data]] = held
    if largest >= CV_LEVERAGE_LIMIT:
        return CrossValidation(math.nan, False, largest, folds,
                               f"a fold of {folds} blocks within the curves has leverage "
                               f"{largest:.2f} (>= {CV_LEVERAGE_LIMIT:g}): the held-out "
                               "points carry nearly all the information on some parameter, "
                               "so the fold's refit is not determined by the rest")
    weight = problem.batch.weight.reshape(-1)
    return CrossValidation(float(problem.noise * math.sqrt(total / np.sum(weight))), True,
                           largest, folds, "", held_out)
