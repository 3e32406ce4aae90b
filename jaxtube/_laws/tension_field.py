"""No-compression (tension-field) membrane tube in pure bending, with a closed-form energy.

Comer & Levy (1963) for ``M_w = pi p r^3 / 2`` and ``M_c = pi p r^3``; the wrinkled branch
and the energy density are in docs/physics.md, section 2.3.
"""

import math
from typing import final

import equinox as eqx
import jax
import jax.numpy as jnp

from .base import (
    COLLAPSED_MOMENT_FRACTION,
    AbstractMomentLaw,
    Array,
    as_float,
    polynomial,
)

# Small-angle series, in powers of a^2, of the taut-arc functions (exact ones lose digits to
# cancellation for small a, i.e. far into the wrinkled regime):
#   g(a) = sin a - a cos a            = a^3 sum_{n>=1} (-1)^(n+1) 2n / (2n+1)! a^(2n-2)
#   n(a) = a - sin a cos a            = a^3 sum_{n>=1} (-1)^(n+1) 4^n / (2n+1)! a^(2n-2)
#   q(a) = a + 2a cos^2 a - 3 sin a cos a = a^5 sum_{n>=2} (-1)^n 4^n (2n-2)/(2n+1)! a^(2n-4)
_SMALL_ANGLE = 0.25
_SERIES_TERMS = 10
_G_SERIES = tuple((-1.0) ** (n + 1) * 2 * n / math.factorial(2 * n + 1)
                  for n in range(1, _SERIES_TERMS))
_N_SERIES = tuple((-1.0) ** (n + 1) * 4.0**n / math.factorial(2 * n + 1)
                  for n in range(1, _SERIES_TERMS))
_Q_SERIES = tuple((-1.0) ** n * 4.0**n * (2 * n - 2) / math.factorial(2 * n + 1)
                  for n in range(2, _SERIES_TERMS + 1))


def _small_angle(angle: Array) -> tuple[Array, Array]:
    """Where the series are used, and the angle there (0 elsewhere, so the unused series
    branch stays tame under differentiation)."""
    small = angle < _SMALL_ANGLE
    return small, jnp.where(small, angle, 0.0)


def _taut_arc_g(angle: Array) -> Array:
    """`g(a) = sin a - a cos a`: `pi kappa_w / kappa` on the wrinkled branch."""
    small, small_angle = _small_angle(angle)
    series = small_angle**3 * polynomial(small_angle**2, _G_SERIES)
    exact = jnp.sin(angle) - angle * jnp.cos(angle)
    return jnp.where(small, series, exact)


def _taut_arc_moment_ratio(angle: Array) -> Array:
    """`(a - sin a cos a) / (sin a - a cos a) = 2 M / M_c`; 1 at a = pi, 2 at a = 0."""
    small, small_angle = _small_angle(angle)
    square = small_angle**2
    series = polynomial(square, _N_SERIES) / polynomial(square, _G_SERIES)
    safe = jnp.where(small, 1.0, angle)
    exact = (safe - jnp.sin(safe) * jnp.cos(safe)) / (jnp.sin(safe) - safe * jnp.cos(safe))
    return jnp.where(small, series, exact)


def _taut_arc_strain_integral(angle: Array) -> Array:
    """`q(a) = a + 2a cos^2 a - 3 sin a cos a = int_{-a}^{a} (cos phi - cos a)^2 dphi`."""
    small, small_angle = _small_angle(angle)
    series = small_angle**5 * polynomial(small_angle**2, _Q_SERIES)
    cosine = jnp.cos(angle)
    exact = angle + 2.0 * angle * cosine**2 - 3.0 * jnp.sin(angle) * cosine
    return jnp.where(small, series, exact)


_HALF_ANGLE_ITERATIONS = 40


@jax.custom_jvp
def _taut_half_angle(arc_function: Array) -> Array:
    """Half-angle `a` in [0, pi] of the taut arc, solving `sin a - a cos a = arc_function`.

    `arc_function = pi kappa_w / kappa`, clipped to [0, pi]. Derivatives by the implicit
    function theorem (`da/dx = 1 / (a sin a)`), so they are exact to any order.
    """
    return _solve_taut_half_angle(arc_function)


@jax.jit  # module-level jit: compiled once per shape, also when called eagerly
def _solve_taut_half_angle(arc_function: Array) -> Array:
    """Safeguarded Newton (bisection on the bracket when a step leaves it), from the
    asymptotic guesses `g ~ a^3/3` (a -> 0) and `g ~ pi - pi (pi - a)^2 / 2` (a -> pi)."""
    target = jnp.clip(arc_function, 0.0, math.pi)
    cube_root = jnp.cbrt(3.0 * target)
    guess = jnp.where(target < 1.5, cube_root * (1.0 + cube_root**2 / 30.0),
                      math.pi - jnp.sqrt(2.0 * (math.pi - target) / math.pi))

    def newton_bisection(_, state):
        angle, low, high = state
        residual = _taut_arc_g(angle) - target
        low = jnp.where(residual <= 0, angle, low)
        high = jnp.where(residual >= 0, angle, high)
        slope = angle * jnp.sin(angle)
        usable = slope > 0
        newton = angle - residual / jnp.where(usable, slope, 1.0)
        inside = usable & (newton >= low) & (newton <= high)
        return jnp.where(inside, newton, 0.5 * (low + high)), low, high

    angle, _, _ = jax.lax.fori_loop(
        0, _HALF_ANGLE_ITERATIONS, newton_bisection,
        (guess, jnp.zeros_like(target), jnp.full_like(target, math.pi)))
    return angle


@_taut_half_angle.defjvp
def _taut_half_angle_jvp(primals, tangents):
    (arc_function,), (arc_function_dot,) = primals, tangents
    angle = _taut_half_angle(arc_function)  # differentiable again: higher orders work
    slope = angle * jnp.sin(angle)  # g'(a)
    active = (slope > 0) & (arc_function > 0) & (arc_function < math.pi)
    angle_dot = jnp.where(active, arc_function_dot / jnp.where(active, slope, 1.0), 0.0)
    return angle, angle_dot


def _wrinkled_energy_at_angle(angle, curvature_sq, wall_modulus, pressure, radius):
    """`W = 1/2 E t kappa^2 r^3 q(a) + pi p r^3 (kappa cos a + kappa_w / 2)` at a given taut
    half-angle `a` (TensionFieldLaw docstring); stationary in `a` at `a(kappa)`."""
    onset = pressure / (2.0 * wall_modulus)
    return (0.5 * wall_modulus * radius**3 * curvature_sq * _taut_arc_strain_integral(angle)
            + math.pi * pressure * radius**3 * (jnp.sqrt(curvature_sq) * jnp.cos(angle)
                                                + 0.5 * onset))


def _wrinkled_half_angle(curvature_sq, wall_modulus, pressure):
    onset = pressure / (2.0 * wall_modulus)
    return _taut_half_angle(math.pi * onset / jnp.sqrt(curvature_sq))


@jax.custom_jvp
def _tension_field_wrinkled_energy(curvature_sq, wall_modulus, pressure, radius):
    """Wrinkled-branch energy density [N] at `curvature_sq > kappa_w^2`.

    Its derivatives use the envelope theorem: `W(kappa, a)` is stationary in `a`, so every
    first derivative is the partial one at fixed `a`, and the rule keeps `a(kappa)`
    differentiable for the higher orders. Differentiating through `a` instead (the chain
    rule `dW/da da/dkappa` with `dW/da = 0` computed as a difference of O(1) terms and
    `da/dkappa ~ 1 / (pi - a)`) made the second derivative wrong by up to 5e6 EI when the
    curvature lay within a few rounding errors above `kappa_w` (measured: -5.4e6 EI at
    `kappa = kappa_w (1 + 4e-16)`, -1.4e4 EI at `1e-14`, 10.6 EI at `1e-12`; the exact value
    there is EI, the law being C1 with `M'' ~ (kappa - kappa_w)^(-1/2)`).
    """
    angle = _wrinkled_half_angle(curvature_sq, wall_modulus, pressure)
    return _wrinkled_energy_at_angle(angle, curvature_sq, wall_modulus, pressure, radius)


@_tension_field_wrinkled_energy.defjvp
def _tension_field_wrinkled_energy_jvp(primals, tangents):
    angle = _wrinkled_half_angle(*primals[:3])  # differentiable: exact higher derivatives
    return jax.jvp(lambda *x: _wrinkled_energy_at_angle(angle, *x), primals, tangents)


@final
class TensionFieldLaw(AbstractMomentLaw):
    """No-compression (tension-field) membrane tube in pure bending (docs/physics.md,
    section 2.3).

    `wall_modulus` = E t [N/m]; `residual_stiffness_ratio` (default 0) adds
    `ratio * EI * kappa` (and its energy) so that the collapsed regime keeps some stiffness.

    - Unwrinkled, `|kappa| <= kappa_w = p / (2 E t)` (independent of r):
      `M = EI kappa`, `EI = pi E t r^3`, `W = EI kappa^2 / 2`.
    - Wrinkled, with the taut half-angle `a` in (0, pi):
      `kappa = pi p / (2 E t g(a))`, `g(a) = sin a - a cos a`, and
      `M = (pi p r^3 / 2) (a - sin a cos a) / g(a)`, from `M_w = pi p r^3 / 2` at `kappa_w`
      up to `M_c = pi p r^3` as `kappa -> inf` (Comer & Levy 1963).

    Energy density (derived here). Take the wall strain `eps = eps0 + kappa r cos(phi)`, taut
    for `|phi| < a`, and the potential per unit length
    `Pi(kappa, eps0) = int 1/2 E t max(eps, 0)^2 r dphi - N eps0` with the end-cap force
    `N = p pi r^2` as a dead load. Stationarity in `eps0` (axial equilibrium) gives the
    `kappa(a)` above with `eps0 = -kappa r cos a`; `dPi/dkappa` gives `M(a)`. Then with
    `q(a) = a + 2a cos^2 a - 3 sin a cos a`, `W = Pi(kappa) - Pi(0)` is
    `W = 1/2 E t kappa^2 r^3 q(a) + pi p r^3 kappa cos a + pi p^2 r^3 / (4 E t)`,
    which equals `EI kappa_w^2 / 2` at `a = pi` (continuous) and is stationary in `a`.
    `a(kappa)` comes from a fixed-iteration safeguarded Newton solve with an implicit
    (`jax.custom_jvp`) derivative, so gradients and Hessians of `W` and `M` are exact.

    Regime: 0 for `|kappa| <= kappa_w`; 2 where the tension-field moment reaches
    `0.95 M_c` (at about `29 kappa_w`); 1 in between. Asymptotically
    `M_c - M ~ M_c (3 pi kappa_w / kappa)^(2/3) / 10`, so M approaches M_c slowly.
    Requires `p > 0` (at `p = 0` the moment vanishes for any wrinkled curvature).
    """

    wall_modulus: Array = eqx.field(converter=as_float)
    residual_stiffness_ratio: Array = eqx.field(default=0.0, converter=as_float)

    def _bending_stiffness(self, radius):
        return math.pi * self.wall_modulus * radius**3

    def _wrinkling_curvature(self, pressure):
        return pressure / (2.0 * self.wall_modulus)

    def _wrinkled_moment(self, magnitude, pressure, radius):
        """Tension-field moment for `magnitude > kappa_w`, and where that holds."""
        onset = self._wrinkling_curvature(pressure)
        wrinkled = magnitude > onset
        safe = jnp.where(wrinkled, magnitude, 1.0)
        arc_function = jnp.where(wrinkled, math.pi * onset / safe, 0.5 * math.pi)
        angle = _taut_half_angle(arc_function)
        collapse_moment = math.pi * pressure * radius**3
        return 0.5 * collapse_moment * _taut_arc_moment_ratio(angle), wrinkled

    def energy_density(self, curvature_sq, pressure, radius):
        curvature_sq, pressure, radius = jnp.broadcast_arrays(
            as_float(curvature_sq), as_float(pressure), as_float(radius))
        stiffness = self._bending_stiffness(radius)
        onset = self._wrinkling_curvature(pressure)
        wrinkled = curvature_sq > onset**2
        safe_sq = jnp.where(wrinkled, curvature_sq, 1.0)
        wrinkled_energy = _tension_field_wrinkled_energy(safe_sq, self.wall_modulus, pressure,
                                                         radius)
        linear_energy = 0.5 * stiffness * curvature_sq
        return (jnp.where(wrinkled, wrinkled_energy, linear_energy)
                + self.residual_stiffness_ratio * linear_energy)

    def moment(self, curvature, pressure, radius):
        curvature, pressure, radius = jnp.broadcast_arrays(
            as_float(curvature), as_float(pressure), as_float(radius))
        stiffness = self._bending_stiffness(radius)
        wrinkled_moment, wrinkled = self._wrinkled_moment(jnp.abs(curvature), pressure,
                                                          radius)
        linear_moment = stiffness * curvature
        return (jnp.where(wrinkled, jnp.sign(curvature) * wrinkled_moment, linear_moment)
                + self.residual_stiffness_ratio * linear_moment)

    def regime(self, curvature, pressure, radius):
        curvature, pressure, radius = jnp.broadcast_arrays(
            as_float(curvature), as_float(pressure), as_float(radius))
        wrinkled_moment, wrinkled = self._wrinkled_moment(jnp.abs(curvature), pressure,
                                                          radius)
        collapsed = wrinkled & (wrinkled_moment
                                >= COLLAPSED_MOMENT_FRACTION * math.pi * pressure * radius**3)
        return jnp.where(collapsed, 2, jnp.where(wrinkled, 1, 0)).astype(jnp.int32)

    def initial_stiffness(self, pressure, radius):
        pressure, radius = jnp.broadcast_arrays(as_float(pressure), as_float(radius))
        return (1.0 + self.residual_stiffness_ratio) * self._bending_stiffness(radius)
