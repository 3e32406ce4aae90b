"""Breukels' (PhD thesis, TU Delft 2011) empirical bending and torsion laws.

The 1 m cantilever fits of docs/physics.md, section 3, written as moment-curvature laws
(p in bar inside the fits).
"""

import math
from typing import final

import jax.numpy as jnp

from .._units import unit_factor
from .base import (
    COLLAPSED_MOMENT_FRACTION,
    WRINKLED_MOMENT_FRACTION,
    AbstractMomentLaw,
    as_float,
    magnitude_from_square,
    polynomial,
)

_PASCAL_PER_BAR = unit_factor("pressure", "bar")
# The fits come from cantilever tests of length 1 m: tip load P = M_root / L and tip
# deflection v = kappa L^2 / 3 (small-deflection cantilever), twist phi = tau L.
_TEST_LENGTH = 1.0  # [m]
# D = (C1 r + C2) p^2 + C3 r^3 + C4: tip-load plateau [N] (p in bar, r in m).
_TIP_LOAD_PLATEAU = (6582.82, -272.43, 40852.38, 14.31)
# N = (C5 r^5 + C6) p + C7 r + C8: initial tip-load slope [N/m].
_TIP_LOAD_SLOPE = (271865251.42, 215.93, 14021.79, -589.05)
# c1 = (C13 r + C14) p + C15 r + C16: torque scale [N m].
_TORQUE_SCALE = (1467.0, 40.908, -191.8, 47.406)
# c2 = C17 r^4 ln(p) + C18 r^3 + C19: twist scale [1/rad].
_TWIST_SCALE = (-17703.0, 358.05, 0.0918)

# Taylor coefficients, in x = |kappa| / k0, of f(x) = x - 1 + exp(-x) (from x^2) and of
# G(x) = (1 - exp(-x)) / x (from x^0), used below x = _SMALL_RATIO.
_SMALL_RATIO = 0.2
_F_SERIES = tuple((-1.0) ** n / math.factorial(n) for n in range(2, 16))
_G_EXP_SERIES = tuple((-1.0) ** n / math.factorial(n + 1) for n in range(0, 14))


@final
class EmpiricalBendingLaw2011(AbstractMomentLaw):
    """Breukels' (2011) empirical bending law as a moment-curvature law.

    From the 1 m cantilever fit `P(v) = D (1 - exp(-(N / D) v))` (docs/physics.md,
    section 3.1; p in bar inside, converted from Pa; r in m):
    `EI0 = N L^3 / 3`, `M_max = D L` (L = 1 m),
    `M = M_max (1 - exp(-EI0 |kappa| / M_max)) sign(kappa)`,
    `W = M_max (|kappa| - k0 (1 - exp(-|kappa| / k0)))`, `k0 = M_max / EI0`.
    `W` has a `|kappa|^3` term; below `|kappa| = 0.2 k0` it is evaluated as a Taylor series
    in `s = kappa^2` and a safe `|kappa|`, so that the gradient and Hessian at exactly zero
    are exact (`0` and `EI0 I`). Reported validity: r about 0.05-0.15 m, 0.1-1 bar.

    Regime (a convention of this package, not of the thesis): 0 while `M < 0.5 M_max`,
    1 while `M < 0.95 M_max`, 2 beyond.
    """

    def _parameters(self, pressure, radius):
        """`(EI0 [N m^2], M_max [N m])`."""
        pressure_bar = as_float(pressure) / _PASCAL_PER_BAR
        radius = as_float(radius)
        c1, c2, c3, c4 = _TIP_LOAD_PLATEAU
        c5, c6, c7, c8 = _TIP_LOAD_SLOPE
        plateau = (c1 * radius + c2) * pressure_bar**2 + c3 * radius**3 + c4
        slope = (c5 * radius**5 + c6) * pressure_bar + c7 * radius + c8
        return slope * _TEST_LENGTH**3 / 3.0, plateau * _TEST_LENGTH

    def energy_density(self, curvature_sq, pressure, radius):
        curvature_sq = as_float(curvature_sq)
        stiffness, maximum = self._parameters(pressure, radius)
        scale = maximum / stiffness  # k0 [1/m]
        ratio = magnitude_from_square(curvature_sq) / scale
        small = ratio < _SMALL_RATIO
        # The series only sees small arguments (no overflow in the unused branch).
        small_ratio = jnp.where(small, ratio, 0.0)
        small_ratio_sq = jnp.where(small, curvature_sq / scale**2, 0.0)
        even = polynomial(small_ratio_sq, _F_SERIES[0::2])
        odd = polynomial(small_ratio_sq, _F_SERIES[1::2])
        series = small_ratio_sq * (even + small_ratio * odd)
        closed = ratio + jnp.expm1(-ratio)
        shape = jnp.where(small, series, closed)
        return stiffness * scale**2 * shape

    def moment(self, curvature, pressure, radius):
        curvature = as_float(curvature)
        stiffness, maximum = self._parameters(pressure, radius)
        ratio = jnp.abs(curvature) / (maximum / stiffness)
        small = ratio < _SMALL_RATIO
        safe = jnp.where(small, 1.0, ratio)
        secant_fraction = jnp.where(small,
                                    polynomial(jnp.where(small, ratio, 0.0), _G_EXP_SERIES),
                                    -jnp.expm1(-safe) / safe)
        return stiffness * curvature * secant_fraction

    def regime(self, curvature, pressure, radius):
        stiffness, maximum = self._parameters(pressure, radius)
        fraction = -jnp.expm1(-jnp.abs(as_float(curvature)) * stiffness / maximum)
        return jnp.where(fraction < WRINKLED_MOMENT_FRACTION, 0,
                         jnp.where(fraction < COLLAPSED_MOMENT_FRACTION, 1, 2)
                         ).astype(jnp.int32)

    def initial_stiffness(self, pressure, radius):
        stiffness, _ = self._parameters(pressure, radius)
        return stiffness


# W = (c1 / c) sum_{n>=0} (-1)^n v^(n+1) / ((2n+1)(2n+2)), v = c^2 tau^2, used below v = 0.04.
_SMALL_TWIST_SQ = 0.04
_TORSION_SERIES = tuple((-1.0) ** n / ((2 * n + 1) * (2 * n + 2)) for n in range(0, 12))


@final
class EmpiricalTorsionLaw2011(AbstractMomentLaw):
    """Breukels' (2011) empirical torsion law, per unit length.

    The fit over a 1 m tube, `T(phi) = c1 atan(c2 phi)` (docs/physics.md, section 3.2;
    p in bar inside, converted from Pa; r in m; phi in rad), becomes with `phi = tau L`, L = 1 m:
    `M_t(tau) = c1 atan(c tau)`, `c = c2 L`, initial stiffness `GJ0 = c1 c`, and
    `W = c1 (tau atan(c tau) - ln(1 + c^2 tau^2) / (2 c))`, an even analytic function
    evaluated as a series in `tau^2` near zero. `curvature` here is the rate of twist
    `tau` [rad/m].

    Regime: always 0 (the thesis defines no torsional wrinkling regimes).
    """

    def _parameters(self, pressure, radius):
        """`(c1 [N m], c [m/rad])`."""
        pressure_bar = as_float(pressure) / _PASCAL_PER_BAR
        radius = as_float(radius)
        c13, c14, c15, c16 = _TORQUE_SCALE
        c17, c18, c19 = _TWIST_SCALE
        torque = (c13 * radius + c14) * pressure_bar + c15 * radius + c16
        twist = c17 * radius**4 * jnp.log(pressure_bar) + c18 * radius**3 + c19
        return torque, twist * _TEST_LENGTH

    def energy_density(self, curvature_sq, pressure, radius):
        curvature_sq = as_float(curvature_sq)
        torque, twist = self._parameters(pressure, radius)
        scaled_sq = twist**2 * curvature_sq
        small = scaled_sq < _SMALL_TWIST_SQ
        small_sq = jnp.where(small, scaled_sq, 0.0)
        series = small_sq * polynomial(small_sq, _TORSION_SERIES)
        rate = jnp.sqrt(jnp.where(small, _SMALL_TWIST_SQ, curvature_sq))
        closed = (twist * rate * jnp.arctan(twist * rate)
                  - 0.5 * jnp.log1p(twist**2 * rate**2))
        return torque / twist * jnp.where(small, series, closed)

    def moment(self, curvature, pressure, radius):
        torque, twist = self._parameters(pressure, radius)
        return torque * jnp.arctan(twist * as_float(curvature))

    def regime(self, curvature, pressure, radius):
        shape = jnp.broadcast_shapes(jnp.shape(curvature), jnp.shape(pressure),
                                     jnp.shape(radius))
        return jnp.zeros(shape, dtype=jnp.int32)

    def initial_stiffness(self, pressure, radius):
        torque, twist = self._parameters(pressure, radius)
        return torque * twist
