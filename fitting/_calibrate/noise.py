"""Model-free estimate of the force noise, with its uncertainty.

Difference-based variance estimation (Rice 1984; Gasser, Sroka & Jennen-Steinmetz,
Biometrika 73, 1986; Hall, Kay & Titterington, Biometrika 77, 1990 for higher orders): on
each curve, ordered by deflection, every window of ``m = order + 2`` consecutive points gives
the pseudo-residual ``e = c . y``, where ``c`` (unit length) is orthogonal to every polynomial
of degree ``order`` evaluated at the window's (unequally spaced) deflections. A curve that is
locally a polynomial of that degree drops out of ``e``, and white noise of variance
``sigma^2`` gives ``E e^2 = sigma^2``. ``order = 1`` is the Gasser et al. three-point
estimator; it assumes the curve is locally linear and runs high where force-deflection curves
bend strongly (the onset of wrinkling, the collapse plateau). The default ``order = 2``
annihilates quadratics over four points, so the bending enters only through the third
derivative; higher orders remove more of the bending but weigh the interior points of a
curve more than its ends and scatter more (on the bundled datasets order 2 was closest to the
generating floors: ``tests/test_noise_estimate.py``).

Noise in the deflection enters the force residuals of a model evaluated at the measured
deflection through the local slope, ``F'(u) sigma_u``; the pseudo-residuals see exactly
that (a shifted abscissa of a locally polynomial curve), so the estimate is of the
*effective* force noise ``sqrt(mean(sigma_F^2 + F'^2 sigma_u^2))``, the floor a model's RMSE
can reach.

Uncertainty: with ``C`` the matrix whose rows are the (overlapping) windows' coefficients,
``S = sum e^2 = eps^T C^T C eps``; for Gaussian white noise ``E S = k sigma^2`` (``k`` rows)
and ``Var S = 2 sigma^4 tr((C^T C)^2)``, so ``sd(sigma_hat) = sigma_hat sqrt(tr((C^T C)^2) /
2) / k`` (delta method), which accounts for the overlap of the windows.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

DEFAULT_ORDER = 2


@dataclasses.dataclass(frozen=True)
class NoiseEstimate:
    """``noise_N``: the estimate [N]; ``standard_error_N``; ``pseudo_residuals``: how many
    windows entered; ``order``: the polynomial degree the differences annihilate."""

    noise_N: float
    standard_error_N: float
    pseudo_residuals: int
    order: int

    def words(self) -> str:
        return (f"{self.noise_N:.3g} +- {self.standard_error_N:.2g} N (model-free, "
                f"differences of order {self.order} over {self.pseudo_residuals} windows)")


def _difference_rows(x: np.ndarray, order: int) -> np.ndarray:
    """``[n - order - 1, n]``: per window, the unit coefficients orthogonal to polynomials of
    degree ``order`` at the window's abscissae (scaled to [-1, 1] for conditioning)."""
    m = order + 2
    n = x.size
    rows = np.zeros((max(n - m + 1, 0), n))
    for i in range(n - m + 1):
        window = x[i:i + m]
        span = max(float(window[-1] - window[0]), 1e-300)
        t = 2.0 * (window - window[0]) / span - 1.0
        vandermonde = np.vander(t, order + 1, increasing=True)  # [m, order + 1]
        _, _, vt = np.linalg.svd(vandermonde.T)
        rows[i, i:i + m] = vt[-1]
    return rows


def estimate_noise_with_error(curves, order: int = DEFAULT_ORDER) -> NoiseEstimate | None:
    """Pooled noise estimate over ``curves`` (objects with ``deflection`` and ``force``
    arrays), of order ``order`` or, when no curve is that long, the highest order the longest
    curve allows; None when no curve has three points."""
    curves = list(curves)
    longest = max((np.size(curve.force) for curve in curves), default=0)
    order = min(order, longest - 2)  # short curves: the highest order they allow
    if order < 1:
        return None
    total, count, trace = 0.0, 0, 0.0
    for curve in curves:
        sort = np.argsort(np.asarray(curve.deflection), kind="stable")
        x = np.asarray(curve.deflection, float)[sort]
        y = np.asarray(curve.force, float)[sort]
        rows = _difference_rows(x, order)
        if rows.shape[0] == 0:
            continue
        e = rows @ y
        total += float(e @ e)
        count += rows.shape[0]
        gram = rows.T @ rows
        trace += float(np.sum(gram * gram))
    if count == 0:
        return None
    sigma = math.sqrt(total / count)
    return NoiseEstimate(noise_N=sigma, standard_error_N=sigma * math.sqrt(trace / 2) / count,
                         pseudo_residuals=count, order=order)


def estimate_noise(data) -> float:
    """Pooled force noise standard deviation [N] of ``data`` (:class:`fitting.MeasuredData`),
    model-free: :func:`estimate_noise_with_error` (its value only)."""
    estimate = estimate_noise_with_error(data)
    if estimate is None:
        raise ValueError(f"{data.source}: too few points per curve to estimate the noise "
                         "(at least three are needed); give it")
    return estimate.noise_N
