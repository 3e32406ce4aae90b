"""Constants, scalar root finding and the tension-field tube law in closed form (numpy).

Part of the independent continuum reference solver (:mod:`fitting.continuum`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

GRAVITY = 9.81  # m/s^2
BAR = 1.0e5  # Pa

# Curvatures beyond this [x 1/L] are capped: only run-away trials get there.
_RUNAWAY_CURVATURE = 1.0e8
# Displacement control gives up beyond this many force scales (0.01 EI / L^2 for a linear law).
_MAX_LOAD_FACTOR = 1.0e8
_SERIES_TERMS = 12
_RUNAWAY_ANGLE = 0.5 * math.pi + 0.25
_RUNAWAY_RESIDUAL = 1.0e3  # residual reported for a run-away shot (asinh never gets there)
_EPS = np.finfo(float).eps


# ---------------------------------------------------------------------------------------
# Element-wise helpers


def _elementwise(scalar_fn: Callable[[float], float], values):
    """Apply a scalar function element-wise; a scalar in gives a Python float out."""
    array = np.asarray(values, dtype=float)
    if array.ndim == 0:
        return scalar_fn(float(array))
    flat = [scalar_fn(float(v)) for v in array.ravel()]
    return np.asarray(flat, dtype=float).reshape(array.shape)


def _safeguarded_newton(fun, target: float, lo: float, hi: float, x0: float) -> float:
    """Root of the increasing function ``fun(x) - target`` on ``[lo, hi]``.

    ``fun`` returns ``(value, derivative)``. Newton steps that leave the bracket are
    replaced by bisection; stops at machine precision in ``x``.
    """
    x = min(max(x0, lo), hi)
    for _ in range(100):
        value, slope = fun(x)
        residual = value - target
        if residual == 0.0:
            return x
        if residual > 0.0:
            hi = x
        else:
            lo = x
        step = residual / slope if slope > 0.0 else math.inf
        x_new = x - step
        if not (lo < x_new < hi):
            x_new = 0.5 * (lo + hi)
        if abs(x_new - x) <= 2.0 * _EPS * abs(x) or hi - lo <= 2.0 * _EPS * abs(x):
            return x_new
        x = x_new
    return x


# ---------------------------------------------------------------------------------------
# Tension-field (no-compression) tube law, docs/physics.md, section 2.3


def _taut_arc_functions(a: float) -> tuple[float, float, float]:
    """``f = sin a - a cos a``, ``w = 2 f - (a - sin a cos a)`` and ``a - sin a``.

    Taylor series below a = 1 (the closed forms cancel catastrophically as a -> 0):
    ``f = sum (-1)^(n+1) 2n a^(2n+1)/(2n+1)!``, ``a - sin a cos a = sum (-1)^(n+1) 4^n
    a^(2n+1)/(2n+1)!``, ``a - sin a = sum (-1)^(n+1) a^(2n+1)/(2n+1)!`` (n >= 1).
    """
    if a < 1.0:
        a2 = a * a
        term = a
        f = w = a_minus_sin = 0.0
        sign = 1.0
        for n in range(1, _SERIES_TERMS + 1):
            term *= a2 / ((2 * n) * (2 * n + 1))
            f += sign * (2 * n) * term
            w += sign * (4 * n - 4**n) * term
            a_minus_sin += sign * term
            sign = -sign
        return f, w, a_minus_sin
    sin_a, cos_a = math.sin(a), math.cos(a)
    f = sin_a - a * cos_a
    return f, 2.0 * f - (a - sin_a * cos_a), a - sin_a


def _check_tube(pressure: float, radius: float, wall_modulus: float) -> None:
    if not (pressure > 0.0 and radius > 0.0 and wall_modulus > 0.0):
        raise ValueError(
            "tension-field law needs pressure > 0 [Pa], radius > 0 [m] and "
            f"wall_modulus (E t) > 0 [N/m]; got {pressure}, {radius}, {wall_modulus}"
        )


def _tension_field_moment_scalar(curvature: float, pressure, radius, wall_modulus) -> float:
    magnitude = abs(curvature)
    if math.isnan(magnitude):
        return math.nan
    onset_curvature = pressure / (2.0 * wall_modulus)
    stiffness = math.pi * wall_modulus * radius**3
    if magnitude <= onset_curvature:
        return stiffness * curvature
    collapse_moment = math.pi * pressure * radius**3
    if math.isinf(magnitude):
        return math.copysign(collapse_moment, curvature)
    # Solve f(a) = pi kappa_w / kappa for the taut half-angle a (f increasing on [0, pi]).
    target = math.pi * onset_curvature / magnitude

    def f_and_slope(a):
        f, _, _ = _taut_arc_functions(a)
        return f, a * math.sin(a)

    guess = min((3.0 * target) ** (1.0 / 3.0), math.pi - math.sqrt(2.0 * (1.0 - target / math.pi)))
    a = _safeguarded_newton(f_and_slope, target, 0.0, math.pi, guess)
    f, w, _ = _taut_arc_functions(a)
    # M = M_w (a - sin a cos a) / f = M_c (1 - w / (2 f)).
    return math.copysign(collapse_moment * (1.0 - w / (2.0 * f)), curvature)


def _tension_field_curvature_scalar(moment: float, pressure, radius, wall_modulus) -> float:
    magnitude = abs(moment)
    if math.isnan(magnitude):
        return math.nan
    stiffness = math.pi * wall_modulus * radius**3
    collapse_moment = math.pi * pressure * radius**3
    if magnitude <= 0.5 * collapse_moment:
        return moment / stiffness
    if magnitude >= collapse_moment:
        return math.copysign(math.inf, moment)
    onset_curvature = pressure / (2.0 * wall_modulus)
    # Solve q(a) = w / (2 f) = 1 - M / M_c (q increasing from 0 at a=0 to 1/2 at a=pi).
    target = 1.0 - magnitude / collapse_moment

    def q_and_slope(a):
        f, w, a_minus_sin = _taut_arc_functions(a)
        sin_a = math.sin(a)
        df = a * sin_a
        dw = 2.0 * sin_a * a_minus_sin
        return w / (2.0 * f), (dw * f - w * df) / (2.0 * f * f)

    guess = min(math.sqrt(10.0 * target), math.pi - 2.0 * math.sqrt(max(0.5 - target, 0.0)))
    a = _safeguarded_newton(q_and_slope, target, 0.0, math.pi, guess)
    f, _, _ = _taut_arc_functions(a)
    return math.copysign(math.pi * onset_curvature / f, moment)


def tension_field_moment(curvature, pressure: float, radius: float, wall_modulus: float):
    """Bending moment [N m] of a no-compression (tension-field) tube at a curvature [1/m].

    Args:
        curvature: scalar or array of any shape [1/m]; the law is odd in it.
        pressure: overpressure p [Pa].
        radius: tube radius r [m].
        wall_modulus: membrane stiffness E t [N/m].

    Returns:
        Moment of the same shape (a float for scalar input) [N m]: ``pi Et r^3 kappa`` up
        to ``kappa_w = p/(2 Et)``, then the parametric wrinkled branch of docs/physics.md,
        section 2.3 (``M -> pi p r^3`` as ``kappa -> inf``).
    """
    _check_tube(pressure, radius, wall_modulus)
    return _elementwise(
        lambda k: _tension_field_moment_scalar(k, pressure, radius, wall_modulus), curvature
    )


def tension_field_curvature(moment, pressure: float, radius: float, wall_modulus: float):
    """Inverse of :func:`tension_field_moment`: curvature [1/m] at a moment [N m].

    Valid for ``|M| < M_c = pi p r^3``; returns ``+-inf`` for ``|M| >= M_c`` (the tube has
    collapsed: no finite curvature carries that moment). Scalar or array input; a float for
    scalar input.
    """
    _check_tube(pressure, radius, wall_modulus)
    return _elementwise(
        lambda m: _tension_field_curvature_scalar(m, pressure, radius, wall_modulus), moment
    )


