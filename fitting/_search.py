"""A one-number search whose every evaluation is a solve: bounded Brent, then both sides.

The studies fit one number at a time (a bending scale, a trailing-edge factor) by
minimising a misfit whose every evaluation is a converged equilibrium. The search is
Brent's bounded minimisation (``scipy.optimize.minimize_scalar(method="bounded")``; Brent
1973, *Algorithms for Minimization without Derivatives*, ch. 5), followed by the misfit a
step ``4 xatol`` to either side of the minimum found, to show it is a minimum.

An evaluation that does not converge has no misfit: the objective returns ``None`` and the
search stops there and says so (a penalty such as ``1e6`` would let Brent walk on as if the
failed point were merely a bad one, and hide the failure in a "converged" search).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

from scipy.optimize import minimize_scalar


class _EvaluationFailed(Exception):
    """Raised inside the search when the objective has no value at ``x``."""

    def __init__(self, x: float):
        self.x = x


@dataclasses.dataclass(frozen=True)
class BoundedSearch:
    """The outcome of :func:`bounded_search`.

    Attributes:
        x: the minimiser found, or the best point evaluated before a failed evaluation
            (``None`` if there was none).
        value: the objective at ``x`` (``None`` with ``x``).
        value_minus_plus: the objective at ``x - step`` and ``x + step`` (``None`` where not
            evaluated or not converged).
        step: the side step, ``4 xatol``.
        converged: Brent's own test passed, ``x`` is not within ``2 xatol`` of a bound,
            neither side is lower, and every evaluation converged.
        at_bound: ``x`` is within ``2 xatol`` of a bound.
        message: Brent's message, or which evaluation did not converge.
        evaluations: calls of the objective, the two sides included.
    """

    x: float | None
    value: float | None
    value_minus_plus: tuple[float | None, float | None]
    step: float
    converged: bool
    at_bound: bool
    message: str
    evaluations: int


def bounded_search(objective: Callable[[float], float | None], bounds: tuple[float, float],
                   xatol: float, max_evaluations: int) -> BoundedSearch:
    """Minimise ``objective(x)`` for ``x`` in ``bounds`` (Brent), then evaluate both sides.

    Args:
        objective: ``x -> value``, or ``None`` when its solve did not converge (the search
            then stops and reports it, converged False).
        bounds: ``(low, high)``.
        xatol: absolute tolerance on ``x`` (Brent's ``xatol``).
        max_evaluations: Brent's iteration cap (the two side evaluations come on top).

    Returns:
        :class:`BoundedSearch`.
    """
    evaluated: list[tuple[float, float]] = []

    def value_at(x: float) -> float:
        value = objective(float(x))
        if value is None or not math.isfinite(value):
            raise _EvaluationFailed(float(x))
        evaluated.append((float(x), float(value)))
        return float(value)

    step = 4 * xatol

    def failed(error: _EvaluationFailed, at_bound: bool = False) -> BoundedSearch:
        best = min(evaluated, key=lambda pair: pair[1], default=(None, None))
        return BoundedSearch(best[0], best[1], (None, None), step, False, at_bound,
                             f"the evaluation at x = {error.x:.6g} did not converge",
                             len(evaluated) + 1)

    try:
        found = minimize_scalar(value_at, bounds=bounds, method="bounded",
                                options={"xatol": xatol, "maxiter": max_evaluations})
    except _EvaluationFailed as error:
        return failed(error)
    x, value = float(found.x), float(found.fun)
    at_bound = min(abs(x - bounds[0]), abs(x - bounds[1])) < 2 * xatol
    try:
        minus, plus = value_at(x - step), value_at(x + step)
    except _EvaluationFailed as error:
        return dataclasses.replace(failed(error, at_bound), x=x, value=value)
    return BoundedSearch(x, value, (minus, plus), step,
                         bool(found.success) and not at_bound and minus >= value <= plus,
                         at_bound, str(found.message), len(evaluated))
