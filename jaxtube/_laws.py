"""Moment-curvature laws of one tube section component (bending or torsion), per unit length.

Every law maps a curvature `kappa` [1/m] (or a rate of twist, for torsion) of one joint to a
moment `M` [N m], and gives the matching energy density `W` [J/m = N] with `dW/dkappa = M`.
The laws are odd and monotone, so `W` is even and convex (PHYSICS.md section 1). They are
`equinox.Module`s; every number is a traced field, so calibration can differentiate with
respect to it. All methods are elementwise and broadcast over `curvature`, `pressure`
(envelope overpressure [Pa]) and `radius` [m]; pressure and radius must be positive.

`energy_density` takes the squared curvature `s = kappa^2` [1/m^2] so that the engine can feed
it `kappa_1^2 + kappa_2^2` (bending from the magnitude of the bending vector, PHYSICS.md
section 1) and take `jax.hessian` with respect to `(kappa_1, kappa_2)`. Each law is written to
give a finite and exact gradient and Hessian there, also at exactly zero curvature: near zero
the energies are polynomials in `s` (or safe-`where` guarded), never `sqrt(s)` of a zero.

Sources:

- `SplineLaw`: Breukels & Ockels, AIAA SDM 2008 (three-regime spline through pivots that
  scale as `A (p r^3)^B`); interpolation by monotone piecewise-cubic Hermite slopes of
  Fritsch & Butland (1984), in the weighted harmonic-mean form of Moler's `pchip`.
- `TensionFieldLaw`: no-compression membrane tube in pure bending (PHYSICS.md section 2;
  Comer & Levy 1963 for `M_w = pi p r^3 / 2` and `M_c = pi p r^3`); the energy density is
  derived here (see the class docstring).
- `EmpiricalBendingLaw2011`, `EmpiricalTorsionLaw2011`: Breukels, PhD thesis, TU Delft 2011,
  the cantilever fits quoted in PHYSICS.md section 3.

Precision: the laws run in the dtype of their inputs and are written for float64 (which
importing `jaxtube` turns on); they stay finite in float32. This module itself never changes
the global JAX configuration.
"""

import abc
import math
from typing import Literal, NamedTuple, final

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import scipy.optimize
from jax.typing import ArrayLike

Array = jax.Array

# Regime thresholds shared by the smooth laws, as fractions of their limiting moment: a
# section counts as wrinkled from half the limit moment (Comer & Levy: M_w = M_c / 2) and as
# collapsed from 95 % of it.
_WRINKLED_MOMENT_FRACTION = 0.5
_COLLAPSED_MOMENT_FRACTION = 0.95


# --------------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------------


def _as_float(x: ArrayLike) -> Array:
    """`x` as a JAX array of a floating dtype (integers go to the default float dtype)."""
    x = jnp.asarray(x)
    if not jnp.issubdtype(x.dtype, jnp.inexact):
        x = x.astype(float)
    return x


def _as_optional_float(x: ArrayLike | None) -> Array | None:
    return None if x is None else _as_float(x)


def _magnitude_from_square(curvature_sq: Array) -> Array:
    """`sqrt(s)` for `s >= 0`, with a finite derivative (taken as 0) at exactly `s = 0`.

    The inner `where` keeps the unused `sqrt` branch away from 0 so that reverse- and
    forward-mode derivatives never form `0 * inf`. Use it only inside expressions whose true
    derivative at zero does not depend on `d sqrt(s) / ds` (odd powers multiplied by `s`).
    """
    positive = curvature_sq > 0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, curvature_sq, 1.0)), 0.0)


def _polynomial(z: Array, coefficients: tuple[float, ...]) -> Array:
    """`sum_n coefficients[n] z^n` by Horner's rule."""
    result = jnp.full_like(z, coefficients[-1])
    for coefficient in reversed(coefficients[:-1]):
        result = result * z + coefficient
    return result


def _concrete_or_none(x: Array) -> np.ndarray | None:
    """The value of `x` as numpy if it is concrete, `None` if it is traced."""
    try:
        return np.asarray(x)
    except (jax.errors.TracerArrayConversionError, jax.errors.ConcretizationTypeError):
        return None


# --------------------------------------------------------------------------------------------
# The interface
# --------------------------------------------------------------------------------------------


class AbstractMomentLaw(eqx.Module):
    """Odd, monotone moment-curvature law of one section component (bending or torsion), per
    unit length.

    Arguments of every method are arrays of any mutually broadcastable shapes; results have
    the broadcast shape. Units: curvature [1/m], pressure = envelope overpressure [Pa],
    radius [m], moment [N m], energy density [J/m = N], stiffness [N m^2].
    """

    @abc.abstractmethod
    def energy_density(self, curvature_sq: ArrayLike, pressure: ArrayLike,
                       radius: ArrayLike) -> Array:
        """Energy density `W(kappa)` [N] with `W(0) = 0`, as a function of `kappa^2` [1/m^2].

        Gradient and Hessian with respect to a curvature vector `(kappa_1, kappa_2)` through
        `curvature_sq = kappa_1^2 + kappa_2^2` are finite and exact, also at exactly zero.
        """

    @abc.abstractmethod
    def moment(self, curvature: ArrayLike, pressure: ArrayLike, radius: ArrayLike) -> Array:
        """Moment `M = dW/dkappa` [N m]; odd and non-decreasing in `curvature` [1/m]."""

    @abc.abstractmethod
    def regime(self, curvature: ArrayLike, pressure: ArrayLike, radius: ArrayLike) -> Array:
        """int32 regime of `|curvature|`: 0 unwrinkled, 1 wrinkled, 2 collapsed."""

    @abc.abstractmethod
    def initial_stiffness(self, pressure: ArrayLike, radius: ArrayLike) -> Array:
        """`dM/dkappa` at zero curvature [N m^2]."""


# --------------------------------------------------------------------------------------------
# Linear law
# --------------------------------------------------------------------------------------------


@final
class LinearLaw(AbstractMomentLaw):
    """Linear law `M = stiffness * kappa`, `W = stiffness * kappa^2 / 2`; always regime 0.

    `stiffness` [N m^2]: scalar or array broadcasting with the evaluation shape. Pressure and
    radius only take part in broadcasting.
    """

    stiffness: Array = eqx.field(converter=_as_float)

    def energy_density(self, curvature_sq, pressure, radius):
        curvature_sq, pressure, radius = jnp.broadcast_arrays(
            _as_float(curvature_sq), _as_float(pressure), _as_float(radius))
        return 0.5 * self.stiffness * curvature_sq

    def moment(self, curvature, pressure, radius):
        curvature, pressure, radius = jnp.broadcast_arrays(
            _as_float(curvature), _as_float(pressure), _as_float(radius))
        return self.stiffness * curvature

    def regime(self, curvature, pressure, radius):
        shape = jnp.broadcast_shapes(jnp.shape(curvature), jnp.shape(pressure),
                                     jnp.shape(radius), jnp.shape(self.stiffness))
        return jnp.zeros(shape, dtype=jnp.int32)

    def initial_stiffness(self, pressure, radius):
        pressure, radius = jnp.broadcast_arrays(_as_float(pressure), _as_float(radius))
        return self.stiffness * jnp.ones_like(pressure)


class ReinforcedLaw(AbstractMomentLaw):
    """A law with a pressure-independent stiffness in parallel: `M = M_base + EI_r kappa`.

    Models tape, seams or a bladder that carry bending whatever the pressure (PHYSICS.md
    section 5: delays wrinkling, lifts the collapse plateau, relatively larger at low
    pressure). The regime is the base law's (the reinforcement does not wrinkle).

    Fields: `base` (any law), `reinforcement_stiffness` EI_r [N m^2] (>= 0).
    """

    base: AbstractMomentLaw
    reinforcement_stiffness: Array = eqx.field(converter=_as_float)

    def energy_density(self, curvature_sq, pressure, radius):
        return (self.base.energy_density(curvature_sq, pressure, radius)
                + 0.5 * self.reinforcement_stiffness * _as_float(curvature_sq))

    def moment(self, curvature, pressure, radius):
        return (self.base.moment(curvature, pressure, radius)
                + self.reinforcement_stiffness * _as_float(curvature))

    def regime(self, curvature, pressure, radius):
        return self.base.regime(curvature, pressure, radius)

    def initial_stiffness(self, pressure, radius):
        return self.base.initial_stiffness(pressure, radius) + self.reinforcement_stiffness


# --------------------------------------------------------------------------------------------
# Spline law (Breukels & Ockels 2008)
# --------------------------------------------------------------------------------------------


class _SplineCoefficients(NamedTuple):
    """Monotone C1 interpolant through (0, 0) and K pivots; arrays of shape (..., K) or (...)."""

    curvatures: Array  # pivot curvatures k_1..k_K
    moments: Array  # pivot moments M_1..M_K
    slopes: Array  # dM/dkappa at the pivots; the last one is the residual slope
    energies: Array  # W at the pivots
    linear_coefficient: Array  # a in M = a kappa + b kappa^3 on [0, k_1]
    cubic_coefficient: Array  # b


@jax.jit
def _spline_coefficients(curvatures: Array, moments: Array,
                         residual_stiffness_ratio: Array) -> _SplineCoefficients:
    zero = jnp.zeros_like(curvatures[..., :1])
    widths = jnp.diff(jnp.concatenate([zero, curvatures], axis=-1), axis=-1)
    secants = jnp.diff(jnp.concatenate([zero, moments], axis=-1), axis=-1) / widths
    # Fritsch & Butland (1984) weighted harmonic mean, as in Moler's pchip; every secant is
    # positive here, so it lies strictly below 3 x either adjacent secant (monotone pieces).
    width_before, width_after = widths[..., :-1], widths[..., 1:]
    secant_before, secant_after = secants[..., :-1], secants[..., 1:]
    weight_before = 2.0 * width_after + width_before
    weight_after = width_after + 2.0 * width_before
    interior_slopes = (weight_before + weight_after) / (
        weight_before / secant_before + weight_after / secant_after)
    # Collapsed-regime slope: 1/k = 1/(ratio * initial secant) + 1/(3 * last secant); written
    # without divisions so that ratio = 0 (a flat tail) stays differentiable.
    initial_secant, last_secant = secants[..., 0], secants[..., -1]
    ratio_secant = residual_stiffness_ratio * initial_secant
    residual_slope = ratio_secant * 3.0 * last_secant / (3.0 * last_secant + ratio_secant)
    slopes = jnp.concatenate([interior_slopes, residual_slope[..., None]], axis=-1)
    # Odd cubic M = a k + b k^3 on [0, k_1] with M(k_1) = M_1, M'(k_1) = d_1.
    first_curvature, first_slope = curvatures[..., 0], slopes[..., 0]
    linear_coefficient = 0.5 * (3.0 * initial_secant - first_slope)
    cubic_coefficient = 0.5 * (first_slope - initial_secant) / first_curvature**2
    first_energy = (0.5 * linear_coefficient * first_curvature**2
                    + 0.25 * cubic_coefficient * first_curvature**4)
    # Exact integral of each cubic Hermite piece: h (M_l + M_r)/2 + h^2 (d_l - d_r)/12.
    piece_energies = (0.5 * width_after * (moments[..., :-1] + moments[..., 1:])
                      + width_after**2 * (slopes[..., :-1] - slopes[..., 1:]) / 12.0)
    energies = first_energy[..., None] + jnp.concatenate(
        [jnp.zeros_like(first_energy[..., None]), jnp.cumsum(piece_energies, axis=-1)],
        axis=-1)
    return _SplineCoefficients(curvatures, moments, slopes, energies, linear_coefficient,
                               cubic_coefficient)


@jax.jit
def _spline_beyond_first_pivot(coefficients: _SplineCoefficients,
                               curvature: Array) -> tuple[Array, Array]:
    """Moment and energy for `curvature >= k_1` (cubic Hermite pieces and the linear tail)."""
    knots = coefficients.curvatures
    pivot_count = knots.shape[-1]
    interval = jnp.sum(knots <= curvature[..., None], axis=-1, dtype=jnp.int32) - 1
    interval = jnp.clip(interval, 0, pivot_count - 1)
    selector = interval[..., None] == jnp.arange(pivot_count, dtype=jnp.int32)

    def pick(values):
        return jnp.sum(jnp.where(selector, values, 0.0), axis=-1)

    def next_knot(values, filler):
        return jnp.concatenate([values[..., 1:], filler], axis=-1)

    left_curvature = pick(knots)
    left_moment = pick(coefficients.moments)
    left_slope = pick(coefficients.slopes)
    left_energy = pick(coefficients.energies)
    # The filler only feeds the unused Hermite branch on the tail; keep its width non-zero.
    right_curvature = pick(next_knot(knots, 2.0 * knots[..., -1:]))
    right_moment = pick(next_knot(coefficients.moments, coefficients.moments[..., -1:]))
    right_slope = pick(next_knot(coefficients.slopes, coefficients.slopes[..., -1:]))

    width = right_curvature - left_curvature
    t = (curvature - left_curvature) / width
    t2, t3, t4 = t**2, t**3, t**4
    hermite_moment = ((2.0 * t3 - 3.0 * t2 + 1.0) * left_moment
                      + (t3 - 2.0 * t2 + t) * width * left_slope
                      + (-2.0 * t3 + 3.0 * t2) * right_moment
                      + (t3 - t2) * width * right_slope)
    hermite_energy = left_energy + width * (
        (0.5 * t4 - t3 + t) * left_moment
        + (0.25 * t4 - 2.0 / 3.0 * t3 + 0.5 * t2) * width * left_slope
        + (-0.5 * t4 + t3) * right_moment
        + (0.25 * t4 - t3 / 3.0) * width * right_slope)

    beyond = curvature - left_curvature
    tail_moment = left_moment + left_slope * beyond
    tail_energy = left_energy + left_moment * beyond + 0.5 * left_slope * beyond**2

    on_tail = interval == pivot_count - 1
    return (jnp.where(on_tail, tail_moment, hermite_moment),
            jnp.where(on_tail, tail_energy, hermite_energy))


@final
class SplineLaw(AbstractMomentLaw):
    """Three-regime spline law of Breukels & Ockels (2008), monotone and C1 by construction.

    **Pivots.** K = sum(pivots_per_regime) pivots `(k_i, M_i)`; the last pivot of regime 1
    is the wrinkling onset, the last of regime 2 the collapse. Increments between
    successive pivots (from (0, 0)) scale as

    - paper form (`curvature_radius_exponent is None`):
      `delta_k_i = curvature_scale_i * (p r^3)^curvature_exponent_i`, likewise for moments;
    - separate form: `delta_k_i = curvature_scale_i * p^curvature_exponent_i *
      r^curvature_radius_exponent_i`, likewise for moments.

    Pivots are cumulative sums of positive increments, so they are strictly increasing for
    any exponents. With equal exponents within one coordinate this is exactly the paper's
    `y = A (p r^3)^B` per pivot.

    **Interpolation.** Knot slopes by the Fritsch-Butland weighted harmonic mean of the
    adjacent secants (Moler's pchip); the slope at the last pivot is the collapsed-regime
    slope `k_res`, `1/k_res = 1/(ratio * delta_0) + 1/(3 delta_last)` (about
    `residual_stiffness_ratio` times the initial secant `delta_0 = M_1/k_1`, never above 3x
    the last secant), and the law continues linearly with that slope beyond the last pivot.
    On `[0, k_1]` the law is the odd cubic `M = a k + b k^3` matching `M_1` and the slope at
    `k_1`; its energy `a s/2 + b s^2/4` is polynomial in `s = k^2`. Other pieces are cubic
    Hermite with closed-form (quartic) energies. Every piece is monotone since every knot
    slope lies in `(0, 3 min(adjacent secants))`.

    Note: collinear regime-1 pivots make the law exactly linear up to the second-to-last
    regime-1 pivot. The last regime-1 piece bends towards the (smaller) wrinkled slope at the
    onset pivot: a C1 law cannot stay linear right up to a knot where the slope must drop to
    keep the next piece monotone.

    **Regime.** 0 while `|kappa| <=` wrinkling onset pivot, 1 while `<=` collapse pivot, else 2.

    Fields (arrays of shape (K,), or (..., K) to broadcast one law per batch element):
    `curvature_scale` [1/m per (unit of the scaling)^exponent], `curvature_exponent`,
    `moment_scale`, `moment_exponent`, `curvature_radius_exponent` and
    `moment_radius_exponent` (both `None` for the paper form), `residual_stiffness_ratio`
    (scalar, default 0.01), static `pivots_per_regime` (default (3, 3, 3)).
    """

    curvature_scale: Array = eqx.field(converter=_as_float)
    curvature_exponent: Array = eqx.field(converter=_as_float)
    moment_scale: Array = eqx.field(converter=_as_float)
    moment_exponent: Array = eqx.field(converter=_as_float)
    curvature_radius_exponent: Array | None = eqx.field(default=None,
                                                        converter=_as_optional_float)
    moment_radius_exponent: Array | None = eqx.field(default=None,
                                                     converter=_as_optional_float)
    residual_stiffness_ratio: Array = eqx.field(default=0.01, converter=_as_float)
    pivots_per_regime: tuple[int, int, int] = eqx.field(default=(3, 3, 3), static=True)

    def __check_init__(self):
        counts = self.pivots_per_regime
        if len(counts) != 3 or any(int(n) != n or n < 1 for n in counts):
            raise ValueError("pivots_per_regime must be three positive integers, got "
                             f"{counts!r}.")
        pivot_count = sum(counts)
        if (self.curvature_radius_exponent is None) != (self.moment_radius_exponent is None):
            raise ValueError("curvature_radius_exponent and moment_radius_exponent must both "
                             "be None (paper form) or both be arrays (separate form).")
        for name in ("curvature_scale", "curvature_exponent", "moment_scale",
                     "moment_exponent", "curvature_radius_exponent",
                     "moment_radius_exponent"):
            value = getattr(self, name)
            if value is not None and (value.ndim == 0 or value.shape[-1] != pivot_count):
                raise ValueError(f"{name} must have shape (..., {pivot_count}) for "
                                 f"pivots_per_regime={counts}, got {value.shape}.")

    def pivots(self, pressure: ArrayLike, radius: ArrayLike) -> tuple[Array, Array]:
        """Pivot curvatures [1/m] and moments [N m], each of shape (..., K).

        `pressure` [Pa] and `radius` [m] broadcast to the batch shape `...`.
        """
        pressure = _as_float(pressure)[..., None]
        radius = _as_float(radius)[..., None]
        if self.curvature_radius_exponent is None:
            scaling = pressure * radius**3
            curvature_steps = self.curvature_scale * scaling**self.curvature_exponent
            moment_steps = self.moment_scale * scaling**self.moment_exponent
        else:
            curvature_steps = (self.curvature_scale * pressure**self.curvature_exponent
                               * radius**self.curvature_radius_exponent)
            moment_steps = (self.moment_scale * pressure**self.moment_exponent
                            * radius**self.moment_radius_exponent)
        curvature_steps, moment_steps = jnp.broadcast_arrays(curvature_steps, moment_steps)
        return jnp.cumsum(curvature_steps, axis=-1), jnp.cumsum(moment_steps, axis=-1)

    def _coefficients(self, pressure, radius) -> _SplineCoefficients:
        curvatures, moments = self.pivots(pressure, radius)
        return _spline_coefficients(curvatures, moments, self.residual_stiffness_ratio)

    def energy_density(self, curvature_sq, pressure, radius):
        curvature_sq = _as_float(curvature_sq)
        spline = self._coefficients(pressure, radius)
        first_sq = spline.curvatures[..., 0] ** 2
        beyond = curvature_sq > first_sq
        curvature = jnp.sqrt(jnp.where(beyond, curvature_sq, first_sq))
        _, outer_energy = _spline_beyond_first_pivot(spline, curvature)
        inner_energy = (0.5 * spline.linear_coefficient * curvature_sq
                        + 0.25 * spline.cubic_coefficient * curvature_sq**2)
        return jnp.where(beyond, outer_energy, inner_energy)

    def moment(self, curvature, pressure, radius):
        curvature = _as_float(curvature)
        spline = self._coefficients(pressure, radius)
        first = spline.curvatures[..., 0]
        magnitude = jnp.abs(curvature)
        beyond = magnitude > first
        outer_moment, _ = _spline_beyond_first_pivot(spline,
                                                     jnp.where(beyond, magnitude, first))
        inner_moment = (spline.linear_coefficient * curvature
                        + spline.cubic_coefficient * curvature**3)
        return jnp.where(beyond, jnp.sign(curvature) * outer_moment, inner_moment)

    def regime(self, curvature, pressure, radius):
        curvatures, _ = self.pivots(pressure, radius)
        unwrinkled_count, wrinkled_count, _ = self.pivots_per_regime
        onset = curvatures[..., unwrinkled_count - 1]
        collapse = curvatures[..., unwrinkled_count + wrinkled_count - 1]
        magnitude = jnp.abs(_as_float(curvature))
        regime = jnp.where(magnitude <= onset, 0, jnp.where(magnitude <= collapse, 1, 2))
        return regime.astype(jnp.int32)

    def initial_stiffness(self, pressure, radius):
        return self._coefficients(pressure, radius).linear_coefficient

    @classmethod
    def from_pivots(cls, curvatures: ArrayLike, moments: ArrayLike,
                    reference_pressure: ArrayLike, reference_radius: ArrayLike,
                    curvature_exponent: ArrayLike = 1.0, moment_exponent: ArrayLike = 1.0,
                    radius_exponents: tuple[ArrayLike, ArrayLike] | None = None,
                    residual_stiffness_ratio: ArrayLike = 0.01,
                    pivots_per_regime: tuple[int, int, int] = (3, 3, 3)) -> "SplineLaw":
        """Law whose pivots at `(reference_pressure [Pa], reference_radius [m])` are given.

        Arguments:
            curvatures, moments: pivot coordinates, shape (K,), K = sum(pivots_per_regime),
                positive and strictly increasing ([1/m] and [N m]).
            curvature_exponent, moment_exponent: scalars or shape (K,); the exponents of
                `p r^3` (paper form) or of `p` (separate form).
            radius_exponents: `None` for the paper form, or the pair
                `(curvature_radius_exponent, moment_radius_exponent)` (scalars or (K,)) for
                the separate form.

        Raises `ValueError` for a wrong pivot count or (when the pivots are concrete)
        pivots that are not positive and strictly increasing.
        """
        curvatures, moments = _as_float(curvatures), _as_float(moments)
        pivot_count = sum(pivots_per_regime)
        for name, values in (("curvatures", curvatures), ("moments", moments)):
            if values.shape != (pivot_count,):
                raise ValueError(f"Pivot {name} must have shape ({pivot_count},) for "
                                 f"pivots_per_regime={tuple(pivots_per_regime)}, got "
                                 f"{values.shape}.")
            concrete = _concrete_or_none(values)
            if concrete is not None and not (concrete[0] > 0 and np.all(np.diff(concrete) > 0)):
                raise ValueError(f"Pivot {name} must be positive and strictly increasing, "
                                 f"got {concrete.tolist()}.")
        zero = jnp.zeros_like(curvatures[:1])
        curvature_steps = jnp.diff(jnp.concatenate([zero, curvatures]))
        moment_steps = jnp.diff(jnp.concatenate([zero, moments]))
        shape = (pivot_count,)
        curvature_exponent = jnp.broadcast_to(_as_float(curvature_exponent), shape)
        moment_exponent = jnp.broadcast_to(_as_float(moment_exponent), shape)
        pressure, radius = _as_float(reference_pressure), _as_float(reference_radius)
        if radius_exponents is None:
            scaling = pressure * radius**3
            curvature_radius_exponent = moment_radius_exponent = None
            curvature_unit = scaling**curvature_exponent
            moment_unit = scaling**moment_exponent
        else:
            curvature_radius_exponent, moment_radius_exponent = (
                jnp.broadcast_to(_as_float(exponent), shape) for exponent in radius_exponents)
            curvature_unit = pressure**curvature_exponent * radius**curvature_radius_exponent
            moment_unit = pressure**moment_exponent * radius**moment_radius_exponent
        return cls(curvature_scale=curvature_steps / curvature_unit,
                   curvature_exponent=curvature_exponent,
                   moment_scale=moment_steps / moment_unit,
                   moment_exponent=moment_exponent,
                   curvature_radius_exponent=curvature_radius_exponent,
                   moment_radius_exponent=moment_radius_exponent,
                   residual_stiffness_ratio=residual_stiffness_ratio,
                   pivots_per_regime=tuple(pivots_per_regime))

    @classmethod
    def from_tension_field(cls, wall_modulus: ArrayLike, pressure: ArrayLike,
                           radius: ArrayLike, *, form: Literal["separate", "paper"] = "separate",
                           residual_stiffness_ratio: ArrayLike = 0.01,
                           collapse_fraction: float = _COLLAPSED_MOMENT_FRACTION,
                           collapsed_extent: float = 10.0,
                           pivots_per_regime: tuple[int, int, int] = (3, 3, 3)) -> "SplineLaw":
        """Spline through samples of `TensionFieldLaw(wall_modulus)` (no residual stiffness).

        Pivots at the reference `(pressure [Pa], radius [m])` (scalars), with
        `kappa_w = p / (2 E t)`: regime 1 equally spaced up to `kappa_w`; regime 2
        geometrically spaced from `kappa_w` to the collapse curvature `kappa_c` where
        `M = collapse_fraction * M_c` (about 29 `kappa_w` for 0.95); regime 3 geometrically
        spaced from `kappa_c` to `collapsed_extent * kappa_c`.

        `form="separate"` (default) gives the exact scaling of the tension-field law,
        curvatures ~ p^1 r^0 and moments ~ p^1 r^3, so the law is right at every (p, r) and
        the reference only fixes where the samples were taken. `form="paper"` uses
        `(p r^3)^1` for both coordinates: exact in p, but the curvatures then (wrongly) scale
        with r^3, so it matches the tension-field law only at the reference radius.

        `wall_modulus` = E t [N/m] may be traced (the pivot positions are fixed multiples of
        `kappa_w`, computed here in numpy).
        """
        if form not in ("separate", "paper"):
            raise ValueError(f"form must be 'separate' or 'paper', got {form!r}.")
        if not 0.5 < collapse_fraction < 1.0:
            raise ValueError("collapse_fraction must lie in (0.5, 1): the tension-field "
                             f"moment runs from M_c/2 to M_c; got {collapse_fraction}.")
        if not collapsed_extent > 1.0:
            raise ValueError(f"collapsed_extent must exceed 1, got {collapsed_extent}.")
        unwrinkled, wrinkled, collapsed = pivots_per_regime

        def moment_fraction(angle):  # M / M_c as a function of the taut half-angle
            return 0.5 * (angle - np.sin(angle) * np.cos(angle)) / (
                np.sin(angle) - angle * np.cos(angle))

        collapse_angle = scipy.optimize.brentq(
            lambda angle: moment_fraction(angle) - collapse_fraction, 1e-3, math.pi - 1e-9,
            xtol=1e-15)
        collapse_multiple = math.pi / (np.sin(collapse_angle)
                                       - collapse_angle * np.cos(collapse_angle))
        multiples = np.concatenate([
            np.arange(1, unwrinkled + 1) / unwrinkled,
            collapse_multiple ** (np.arange(1, wrinkled + 1) / wrinkled),
            collapse_multiple * collapsed_extent ** (np.arange(1, collapsed + 1) / collapsed),
        ])
        tension_field = TensionFieldLaw(wall_modulus)
        pressure, radius = _as_float(pressure), _as_float(radius)
        curvatures = jnp.asarray(multiples, dtype=pressure.dtype) * (
            pressure / (2.0 * tension_field.wall_modulus))
        moments = tension_field.moment(curvatures, pressure, radius)
        radius_exponents = (0.0, 3.0) if form == "separate" else None
        return cls.from_pivots(curvatures, moments, pressure, radius, curvature_exponent=1.0,
                               moment_exponent=1.0, radius_exponents=radius_exponents,
                               residual_stiffness_ratio=residual_stiffness_ratio,
                               pivots_per_regime=tuple(pivots_per_regime))


# --------------------------------------------------------------------------------------------
# Tension-field (no-compression membrane) law
# --------------------------------------------------------------------------------------------

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
    series = small_angle**3 * _polynomial(small_angle**2, _G_SERIES)
    exact = jnp.sin(angle) - angle * jnp.cos(angle)
    return jnp.where(small, series, exact)


def _taut_arc_moment_ratio(angle: Array) -> Array:
    """`(a - sin a cos a) / (sin a - a cos a) = 2 M / M_c`; 1 at a = pi, 2 at a = 0."""
    small, small_angle = _small_angle(angle)
    square = small_angle**2
    series = _polynomial(square, _N_SERIES) / _polynomial(square, _G_SERIES)
    safe = jnp.where(small, 1.0, angle)
    exact = (safe - jnp.sin(safe) * jnp.cos(safe)) / (jnp.sin(safe) - safe * jnp.cos(safe))
    return jnp.where(small, series, exact)


def _taut_arc_strain_integral(angle: Array) -> Array:
    """`q(a) = a + 2a cos^2 a - 3 sin a cos a = int_{-a}^{a} (cos phi - cos a)^2 dphi`."""
    small, small_angle = _small_angle(angle)
    series = small_angle**5 * _polynomial(small_angle**2, _Q_SERIES)
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
    """No-compression (tension-field) membrane tube in pure bending (PHYSICS.md section 2).

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

    wall_modulus: Array = eqx.field(converter=_as_float)
    residual_stiffness_ratio: Array = eqx.field(default=0.0, converter=_as_float)

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
            _as_float(curvature_sq), _as_float(pressure), _as_float(radius))
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
            _as_float(curvature), _as_float(pressure), _as_float(radius))
        stiffness = self._bending_stiffness(radius)
        wrinkled_moment, wrinkled = self._wrinkled_moment(jnp.abs(curvature), pressure,
                                                          radius)
        linear_moment = stiffness * curvature
        return (jnp.where(wrinkled, jnp.sign(curvature) * wrinkled_moment, linear_moment)
                + self.residual_stiffness_ratio * linear_moment)

    def regime(self, curvature, pressure, radius):
        curvature, pressure, radius = jnp.broadcast_arrays(
            _as_float(curvature), _as_float(pressure), _as_float(radius))
        wrinkled_moment, wrinkled = self._wrinkled_moment(jnp.abs(curvature), pressure,
                                                          radius)
        collapsed = wrinkled & (wrinkled_moment
                                >= _COLLAPSED_MOMENT_FRACTION * math.pi * pressure * radius**3)
        return jnp.where(collapsed, 2, jnp.where(wrinkled, 1, 0)).astype(jnp.int32)

    def initial_stiffness(self, pressure, radius):
        pressure, radius = jnp.broadcast_arrays(_as_float(pressure), _as_float(radius))
        return (1.0 + self.residual_stiffness_ratio) * self._bending_stiffness(radius)


# --------------------------------------------------------------------------------------------
# Empirical laws of Breukels (PhD thesis, TU Delft 2011), PHYSICS.md section 3
# --------------------------------------------------------------------------------------------

_PASCAL_PER_BAR = 1.0e5
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

    From the 1 m cantilever fit `P(v) = D (1 - exp(-(N / D) v))` (PHYSICS.md section 3;
    p in bar inside, converted from Pa; r in m):
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
        pressure_bar = _as_float(pressure) / _PASCAL_PER_BAR
        radius = _as_float(radius)
        c1, c2, c3, c4 = _TIP_LOAD_PLATEAU
        c5, c6, c7, c8 = _TIP_LOAD_SLOPE
        plateau = (c1 * radius + c2) * pressure_bar**2 + c3 * radius**3 + c4
        slope = (c5 * radius**5 + c6) * pressure_bar + c7 * radius + c8
        return slope * _TEST_LENGTH**3 / 3.0, plateau * _TEST_LENGTH

    def energy_density(self, curvature_sq, pressure, radius):
        curvature_sq = _as_float(curvature_sq)
        stiffness, maximum = self._parameters(pressure, radius)
        scale = maximum / stiffness  # k0 [1/m]
        ratio = _magnitude_from_square(curvature_sq) / scale
        small = ratio < _SMALL_RATIO
        # The series only sees small arguments (no overflow in the unused branch).
        small_ratio = jnp.where(small, ratio, 0.0)
        small_ratio_sq = jnp.where(small, curvature_sq / scale**2, 0.0)
        even = _polynomial(small_ratio_sq, _F_SERIES[0::2])
        odd = _polynomial(small_ratio_sq, _F_SERIES[1::2])
        series = small_ratio_sq * (even + small_ratio * odd)
        closed = ratio + jnp.expm1(-ratio)
        shape = jnp.where(small, series, closed)
        return stiffness * scale**2 * shape

    def moment(self, curvature, pressure, radius):
        curvature = _as_float(curvature)
        stiffness, maximum = self._parameters(pressure, radius)
        ratio = jnp.abs(curvature) / (maximum / stiffness)
        small = ratio < _SMALL_RATIO
        safe = jnp.where(small, 1.0, ratio)
        secant_fraction = jnp.where(small,
                                    _polynomial(jnp.where(small, ratio, 0.0), _G_EXP_SERIES),
                                    -jnp.expm1(-safe) / safe)
        return stiffness * curvature * secant_fraction

    def regime(self, curvature, pressure, radius):
        stiffness, maximum = self._parameters(pressure, radius)
        fraction = -jnp.expm1(-jnp.abs(_as_float(curvature)) * stiffness / maximum)
        return jnp.where(fraction < _WRINKLED_MOMENT_FRACTION, 0,
                         jnp.where(fraction < _COLLAPSED_MOMENT_FRACTION, 1, 2)
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

    The fit over a 1 m tube, `T(phi) = c1 atan(c2 phi)` (PHYSICS.md section 3; p in bar
    inside, converted from Pa; r in m; phi in rad), becomes with `phi = tau L`, L = 1 m:
    `M_t(tau) = c1 atan(c tau)`, `c = c2 L`, initial stiffness `GJ0 = c1 c`, and
    `W = c1 (tau atan(c tau) - ln(1 + c^2 tau^2) / (2 c))`, an even analytic function
    evaluated as a series in `tau^2` near zero. `curvature` here is the rate of twist
    `tau` [rad/m].

    Regime: always 0 (the thesis defines no torsional wrinkling regimes).
    """

    def _parameters(self, pressure, radius):
        """`(c1 [N m], c [m/rad])`."""
        pressure_bar = _as_float(pressure) / _PASCAL_PER_BAR
        radius = _as_float(radius)
        c13, c14, c15, c16 = _TORQUE_SCALE
        c17, c18, c19 = _TWIST_SCALE
        torque = (c13 * radius + c14) * pressure_bar + c15 * radius + c16
        twist = c17 * radius**4 * jnp.log(pressure_bar) + c18 * radius**3 + c19
        return torque, twist * _TEST_LENGTH

    def energy_density(self, curvature_sq, pressure, radius):
        curvature_sq = _as_float(curvature_sq)
        torque, twist = self._parameters(pressure, radius)
        scaled_sq = twist**2 * curvature_sq
        small = scaled_sq < _SMALL_TWIST_SQ
        small_sq = jnp.where(small, scaled_sq, 0.0)
        series = small_sq * _polynomial(small_sq, _TORSION_SERIES)
        rate = jnp.sqrt(jnp.where(small, _SMALL_TWIST_SQ, curvature_sq))
        closed = (twist * rate * jnp.arctan(twist * rate)
                  - 0.5 * jnp.log1p(twist**2 * rate**2))
        return torque / twist * jnp.where(small, series, closed)

    def moment(self, curvature, pressure, radius):
        torque, twist = self._parameters(pressure, radius)
        return torque * jnp.arctan(twist * _as_float(curvature))

    def regime(self, curvature, pressure, radius):
        shape = jnp.broadcast_shapes(jnp.shape(curvature), jnp.shape(pressure),
                                     jnp.shape(radius))
        return jnp.zeros(shape, dtype=jnp.int32)

    def initial_stiffness(self, pressure, radius):
        torque, twist = self._parameters(pressure, radius)
        return torque * twist
