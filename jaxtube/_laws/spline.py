"""The three-regime spline law of Breukels & Ockels (2008), monotone and C1 by construction.

Pivots scale as ``A (p r^3)^B`` (docs/physics.md, section 1.1); interpolation by monotone
piecewise-cubic Hermite slopes of Fritsch & Butland (1984), in the weighted harmonic-mean
form of Moler's ``pchip``.
"""

import math
from typing import Literal, NamedTuple, final

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import scipy.optimize
from jax.typing import ArrayLike

from .base import (
    COLLAPSED_MOMENT_FRACTION,
    AbstractMomentLaw,
    Array,
    as_float,
    as_optional_float,
    concrete_or_none,
)
from .tension_field import TensionFieldLaw


class _SplineCoefficients(NamedTuple):
    """Monotone C1 interpolant through (0, 0) and K pivots; arrays of shape (..., K) or (...)."""

    curvatures: Array  # pivot curvatures k_1..k_K
    moments: Array  # pivot moments M_1..M_K
    slopes: Array  # dM/dkappa at the pivots; the last one is the residual slope
    energies: Array  # W at the pivots
    linear_coefficient: Array  # a in M = a kappa + b max(kappa - k_0, 0)^3 on [0, k_1]
    cubic_coefficient: Array  # b
    linear_end: Array  # k_0 = linear_share * k_1: the law is linear, a kappa, on [0, k_0]


@jax.jit
def _spline_coefficients(curvatures: Array, moments: Array, residual_stiffness_ratio: Array,
                         linear_share: Array) -> _SplineCoefficients:
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
    # First piece on [0, k_1]: M = a k + b max(k - k_0, 0)^3 with k_0 = share * k_1, i.e. linear
    # up to k_0, then a cubic that is C2 there (M'' = 0) and meets M(k_1) = M_1, M'(k_1) = d_1:
    # a = (3 M_1 - d_1 w) / (3 k_1 - w), b = (M_1 - a k_1) / w^3, w = k_1 - k_0. At share 0
    # this is the odd cubic a = (3 s_1 - d_1) / 2, b = (d_1 - s_1) / (2 k_1^2), s_1 = M_1 / k_1.
    first_curvature, first_slope = curvatures[..., 0], slopes[..., 0]
    first_moment = moments[..., 0]
    linear_end = linear_share * first_curvature
    bend_width = first_curvature - linear_end
    linear_coefficient = ((3.0 * first_moment - first_slope * bend_width)
                          / (3.0 * first_curvature - bend_width))
    cubic_coefficient = (first_moment - linear_coefficient * first_curvature) / bend_width**3
    first_energy = (0.5 * linear_coefficient * first_curvature**2
                    + 0.25 * cubic_coefficient * bend_width**4)
    # Exact integral of each cubic Hermite piece: h (M_l + M_r)/2 + h^2 (d_l - d_r)/12.
    piece_energies = (0.5 * width_after * (moments[..., :-1] + moments[..., 1:])
                      + width_after**2 * (slopes[..., :-1] - slopes[..., 1:]) / 12.0)
    energies = first_energy[..., None] + jnp.concatenate(
        [jnp.zeros_like(first_energy[..., None]), jnp.cumsum(piece_energies, axis=-1)],
        axis=-1)
    return _SplineCoefficients(curvatures, moments, slopes, energies, linear_coefficient,
                               cubic_coefficient, linear_end)


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


def _bend_excess(curvature_sq: Array, linear_end: Array) -> Array:
    """`max(|kappa| - k_0, 0)` from `kappa^2`, differentiable everywhere: zero (with zero
    derivatives) where `kappa^2 <= k_0^2`, so the square root never sees 0 (at `k_0 = 0` the
    energy's term `(kappa^2)^2` then has the right first derivative, 0, at `kappa = 0`)."""
    bent = curvature_sq > linear_end**2
    magnitude = jnp.sqrt(jnp.where(bent, curvature_sq, 1.0))
    return jnp.where(bent, magnitude - linear_end, 0.0)


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
    On `[0, k_1]` the law is `M = a k + b max(k - k_0, 0)^3`, linear up to
    `k_0 = linear_share * k_1` and then a cubic that is C2 at `k_0` and matches `M_1` and the
    slope `d_1` at `k_1`: `a = (3 M_1 - d_1 w) / (3 k_1 - w)`, `b = (M_1 - a k_1) / w^3`,
    `w = k_1 - k_0`; energy `a s/2 + b max(k - k_0, 0)^4 / 4` with `s = k^2`. The default
    `linear_share = 0` is the odd cubic `M = a k + b k^3` (energy polynomial in `s`);
    `linear_share -> 1` makes the unwrinkled regime linear up to the onset, as a membrane
    tube is (`EI = pi E t r^3` until wrinkling; docs/physics.md, sections 1.1 and 2.3).
    Other pieces are cubic Hermite with closed-form (quartic) energies. Every piece is
    monotone since every knot slope lies in `(0, 3 min(adjacent secants))` (on `[k_0, k_1]`
    the slope runs monotonically from `a > 0` to `d_1 > 0`).

    Note: collinear regime-1 pivots make the law exactly linear up to the second-to-last
    regime-1 pivot. The last regime-1 piece bends towards the (smaller) wrinkled slope at the
    onset pivot: a C1 law cannot stay linear right up to a knot where the slope must drop to
    keep the next piece monotone.

    **Regime.** 0 while `|kappa| <=` wrinkling onset pivot, 1 while `<=` collapse pivot, else 2.

    Fields (arrays of shape (K,), or (..., K) to broadcast one law per batch element):
    `curvature_scale` [1/m per (unit of the scaling)^exponent], `curvature_exponent`,
    `moment_scale`, `moment_exponent`, `curvature_radius_exponent` and
    `moment_radius_exponent` (both `None` for the paper form), `residual_stiffness_ratio`
    (scalar, default 0.01), `linear_share` (scalar or (...), in [0, 1), default 0: the
    share of the first pivot's curvature over which the law is linear), static
    `pivots_per_regime` (default (3, 3, 3)).
    """

    curvature_scale: Array = eqx.field(converter=as_float)
    curvature_exponent: Array = eqx.field(converter=as_float)
    moment_scale: Array = eqx.field(converter=as_float)
    moment_exponent: Array = eqx.field(converter=as_float)
    curvature_radius_exponent: Array | None = eqx.field(default=None,
                                                        converter=as_optional_float)
    moment_radius_exponent: Array | None = eqx.field(default=None,
                                                     converter=as_optional_float)
    residual_stiffness_ratio: Array = eqx.field(default=0.01, converter=as_float)
    linear_share: Array = eqx.field(default=0.0, converter=as_float)
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
        share = concrete_or_none(self.linear_share)
        if share is not None and not np.all((share >= 0.0) & (share < 1.0)):
            raise ValueError(f"linear_share must lie in [0, 1), got {share.tolist()}.")

    def pivots(self, pressure: ArrayLike, radius: ArrayLike) -> tuple[Array, Array]:
        """Pivot curvatures [1/m] and moments [N m], each of shape (..., K).

        `pressure` [Pa] and `radius` [m] broadcast to the batch shape `...`.
        """
        pressure = as_float(pressure)[..., None]
        radius = as_float(radius)[..., None]
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
        return _spline_coefficients(curvatures, moments, self.residual_stiffness_ratio,
                                    self.linear_share)

    def energy_density(self, curvature_sq, pressure, radius):
        curvature_sq = as_float(curvature_sq)
        spline = self._coefficients(pressure, radius)
        first_sq = spline.curvatures[..., 0] ** 2
        beyond = curvature_sq > first_sq
        curvature = jnp.sqrt(jnp.where(beyond, curvature_sq, first_sq))
        _, outer_energy = _spline_beyond_first_pivot(spline, curvature)
        inner_energy = (0.5 * spline.linear_coefficient * curvature_sq
                        + 0.25 * spline.cubic_coefficient
                        * _bend_excess(curvature_sq, spline.linear_end) ** 4)
        return jnp.where(beyond, outer_energy, inner_energy)

    def moment(self, curvature, pressure, radius):
        curvature = as_float(curvature)
        spline = self._coefficients(pressure, radius)
        first = spline.curvatures[..., 0]
        magnitude = jnp.abs(curvature)
        beyond = magnitude > first
        outer_moment, _ = _spline_beyond_first_pivot(spline,
                                                     jnp.where(beyond, magnitude, first))
        inner_moment = (spline.linear_coefficient * curvature + jnp.sign(curvature)
                        * spline.cubic_coefficient
                        * _bend_excess(curvature**2, spline.linear_end) ** 3)
        return jnp.where(beyond, jnp.sign(curvature) * outer_moment, inner_moment)

    def regime(self, curvature, pressure, radius):
        curvatures, _ = self.pivots(pressure, radius)
        unwrinkled_count, wrinkled_count, _ = self.pivots_per_regime
        onset = curvatures[..., unwrinkled_count - 1]
        collapse = curvatures[..., unwrinkled_count + wrinkled_count - 1]
        magnitude = jnp.abs(as_float(curvature))
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
                    pivots_per_regime: tuple[int, int, int] = (3, 3, 3),
                    linear_share: ArrayLike = 0.0) -> "SplineLaw":
        """Law whose pivots at `(reference_pressure [Pa], reference_radius [m])` are given.

        Arguments:
            curvatures: pivot curvatures, shape (K,), K = sum(pivots_per_regime), positive
                and strictly increasing [1/m].
            moments: pivot moments, shape (K,), positive and strictly increasing [N m].
            curvature_exponent: scalar or shape (K,); the exponent of the curvatures in
                `p r^3` (paper form) or in `p` (separate form).
            moment_exponent: scalar or shape (K,); the same for the moments.
            radius_exponents: `None` for the paper form, or the pair
                `(curvature_radius_exponent, moment_radius_exponent)` (scalars or (K,)) for
                the separate form.
            linear_share: share of the first pivot's curvature over which the law is
                linear (class docstring), in [0, 1).

        Raises `ValueError` for a wrong pivot count or (when the pivots are concrete)
        pivots that are not positive and strictly increasing.
        """
        curvatures, moments = as_float(curvatures), as_float(moments)
        pivot_count = sum(pivots_per_regime)
        for name, values in (("curvatures", curvatures), ("moments", moments)):
            if values.shape != (pivot_count,):
                raise ValueError(f"Pivot {name} must have shape ({pivot_count},) for "
                                 f"pivots_per_regime={tuple(pivots_per_regime)}, got "
                                 f"{values.shape}.")
            concrete = concrete_or_none(values)
            if concrete is not None and not (concrete[0] > 0 and np.all(np.diff(concrete) > 0)):
                raise ValueError(f"Pivot {name} must be positive and strictly increasing, "
                                 f"got {concrete.tolist()}.")
        zero = jnp.zeros_like(curvatures[:1])
        curvature_steps = jnp.diff(jnp.concatenate([zero, curvatures]))
        moment_steps = jnp.diff(jnp.concatenate([zero, moments]))
        shape = (pivot_count,)
        curvature_exponent = jnp.broadcast_to(as_float(curvature_exponent), shape)
        moment_exponent = jnp.broadcast_to(as_float(moment_exponent), shape)
        pressure, radius = as_float(reference_pressure), as_float(reference_radius)
        if radius_exponents is None:
            scaling = pressure * radius**3
            curvature_radius_exponent = moment_radius_exponent = None
            curvature_unit = scaling**curvature_exponent
            moment_unit = scaling**moment_exponent
        else:
            curvature_radius_exponent, moment_radius_exponent = (
                jnp.broadcast_to(as_float(exponent), shape) for exponent in radius_exponents)
            curvature_unit = pressure**curvature_exponent * radius**curvature_radius_exponent
            moment_unit = pressure**moment_exponent * radius**moment_radius_exponent
        return cls(curvature_scale=curvature_steps / curvature_unit,
                   curvature_exponent=curvature_exponent,
                   moment_scale=moment_steps / moment_unit,
                   moment_exponent=moment_exponent,
                   curvature_radius_exponent=curvature_radius_exponent,
                   moment_radius_exponent=moment_radius_exponent,
                   residual_stiffness_ratio=residual_stiffness_ratio,
                   linear_share=linear_share,
                   pivots_per_regime=tuple(pivots_per_regime))

    @classmethod
    def from_tension_field(cls, wall_modulus: ArrayLike, pressure: ArrayLike,
                           radius: ArrayLike, *, form: Literal["separate", "paper"] = "separate",
                           residual_stiffness_ratio: ArrayLike = 0.01,
                           collapse_fraction: float = COLLAPSED_MOMENT_FRACTION,
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
        pressure, radius = as_float(pressure), as_float(radius)
        curvatures = jnp.asarray(multiples, dtype=pressure.dtype) * (
            pressure / (2.0 * tension_field.wall_modulus))
        moments = tension_field.moment(curvatures, pressure, radius)
        radius_exponents = (0.0, 3.0) if form == "separate" else None
        return cls.from_pivots(curvatures, moments, pressure, radius, curvature_exponent=1.0,
                               moment_exponent=1.0, radius_exponents=radius_exponents,
                               residual_stiffness_ratio=residual_stiffness_ratio,
                               pivots_per_regime=tuple(pivots_per_regime))
