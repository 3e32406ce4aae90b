"""Tests of the moment-curvature laws (jaxtube/_laws/)."""

import math

import equinox as eqx
import hypothesis.extra.numpy as hnp
import hypothesis.strategies as st
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.integrate
from hypothesis import HealthCheck, given, settings

from jaxtube._laws import (
    AbstractMomentLaw,
    EmpiricalBendingLaw2011,
    EmpiricalTorsionLaw2011,
    LinearLaw,
    SplineLaw,
    TensionFieldLaw,
)

PRESSURE = 2.0e4  # [Pa], 0.2 bar
RADIUS = 0.075  # [m]
WALL_MODULUS = 2.0e5  # E t [N/m]
WRINKLING_CURVATURE = PRESSURE / (2.0 * WALL_MODULUS)  # [1/m]
BENDING_STIFFNESS = math.pi * WALL_MODULUS * RADIUS**3  # [N m^2]
COLLAPSE_MOMENT = math.pi * PRESSURE * RADIUS**3  # [N m]


# Each jitted helper takes the law as an argument: every numeric field of a law is an array
# leaf, so laws of one structure share a compilation.


@jax.jit
def _moment(law, curvature, pressure, radius):
    return law.moment(curvature, pressure, radius)


@jax.jit
def _energy(law, curvature, pressure, radius):
    return law.energy_density(curvature**2, pressure, radius)


@jax.jit
def _regime(law, curvature, pressure, radius):
    return law.regime(curvature, pressure, radius)


def _moment_and_tangent(law, curvature, pressure, radius):
    """M and dM/dkappa (forward mode; elementwise because the law is)."""
    return jax.jvp(lambda k: law.moment(k, pressure, radius), (curvature,),
                   (jnp.ones_like(curvature),))


@jax.jit
def _vector_derivatives(law, vectors, pressure, radius):
    """W, gradient and Hessian of W(k1^2 + k2^2) at bending vectors of shape (n, 2); the
    Hessian is formed as `jax.hessian` forms it (forward over reverse mode)."""
    def energy(vector):
        return law.energy_density(vector[0] ** 2 + vector[1] ** 2, pressure, radius)

    def gradient_with_aux(vector):
        value, gradient = jax.value_and_grad(energy)(vector)
        return gradient, (value, gradient)

    hessians, (values, gradients) = jax.vmap(
        jax.jacfwd(gradient_with_aux, has_aux=True))(vectors)
    return values, gradients, hessians


def _quad_energy(law, curvature, pressure, radius, breakpoints=()):
    """W(kappa) by scipy quadrature of the moment from 0 to kappa."""
    def integrand(k):
        return float(_moment(law, k, pressure, radius))
    inside = [b for b in breakpoints if 0 < b < curvature]
    value, _ = scipy.integrate.quad(integrand, 0.0, curvature, points=inside or None,
                                    epsabs=0.0, epsrel=1e-12, limit=200)
    return value


# ------------------------------------------------------------------------------------------
# Generic properties of every law, from one compiled profile per law
# ------------------------------------------------------------------------------------------

# Every law, with its initial stiffness computed by hand at (PRESSURE, RADIUS) and a
# characteristic curvature that reaches its far regime. (The paper-form spline and the
# tension-field law with residual stiffness are covered in their own sections.)
_TORSION_TORQUE = (1467.0 * RADIUS + 40.908) * 0.2 - 191.8 * RADIUS + 47.406
_TORSION_TWIST = -17703.0 * RADIUS**4 * math.log(0.2) + 358.05 * RADIUS**3 + 0.0918
_BENDING_2011_STIFFNESS = ((271865251.42 * RADIUS**5 + 215.93) * 0.2 + 14021.79 * RADIUS
                           - 589.05) / 3.0

# A one-pivot-per-regime spline, linear over 60 % of its first pivot; its initial stiffness
# by hand: the Fritsch-Butland slope d_1 at the first pivot, then a = (3 M_1 - d_1 w) /
# (3 k_1 - w), w = (1 - 0.6) k_1 (SplineLaw docstring).
_SHARE_PIVOTS = (np.array([0.05, 0.5, 2.0]), np.array([10.0, 18.0, 20.0]))
_SHARE_LAW = SplineLaw.from_pivots(*_SHARE_PIVOTS, PRESSURE, RADIUS, pivots_per_regime=(1, 1, 1),
                                   linear_share=0.6)


def _first_pivot_slope(curvatures, moments):
    widths = np.diff(np.concatenate([[0.0], curvatures]))
    secants = np.diff(np.concatenate([[0.0], moments])) / widths
    weight_before, weight_after = 2 * widths[1] + widths[0], widths[1] + 2 * widths[0]
    return (weight_before + weight_after) / (weight_before / secants[0]
                                             + weight_after / secants[1])


def _first_piece(curvatures, moments, share):
    """(a, b, k_0) of M = a k + b max(k - k_0, 0)^3 on [0, k_1], by hand."""
    k1, m1 = curvatures[0], moments[0]
    d1 = _first_pivot_slope(curvatures, moments)
    width = (1.0 - share) * k1
    a = (3.0 * m1 - d1 * width) / (3.0 * k1 - width)
    return a, (m1 - a * k1) / width**3, share * k1


_SHARE_STIFFNESS = _first_piece(*_SHARE_PIVOTS, 0.6)[0]

LAW_CASES = {
    "linear": (LinearLaw(150.0), 150.0, 1.0),
    "tension_field": (TensionFieldLaw(WALL_MODULUS), BENDING_STIFFNESS,
                      300.0 * WRINKLING_CURVATURE),
    "spline_separate": (SplineLaw.from_tension_field(WALL_MODULUS, PRESSURE, RADIUS),
                        BENDING_STIFFNESS, 600.0 * WRINKLING_CURVATURE),
    "spline_linear_share": (_SHARE_LAW, _SHARE_STIFFNESS, 3.0),
    "bending_2011": (EmpiricalBendingLaw2011(), _BENDING_2011_STIFFNESS, 2.0),
    "torsion_2011": (EmpiricalTorsionLaw2011(), _TORSION_TWIST * _TORSION_TORQUE, 10.0),
}

# Curvatures as fractions of the characteristic curvature: a dense grid out to 2x (for
# monotonicity) and a geometric one down to 1e-6 (near zero).
_DENSE = 2001
_GRID = np.concatenate([np.linspace(0.0, 2.0, _DENSE), np.geomspace(1e-6, 1.0, 55)])
_FD_STEP = 1e-6
_QUAD_TARGETS = np.array([1e-3, 0.01, 0.1, 0.3, 1.0])
_DIRECTION = np.array([math.cos(0.7), math.sin(0.7)])
_DIRECTIONAL_MAGNITUDES = np.array([0.002, 0.05, 0.3, 1.0, 1e6])  # 1e6: far out
# Bending vectors: exactly zero, then near zero (absolute, 1e-8 1/m).
_NEAR_ZERO_VECTORS = np.array([[0.0, 0.0], [1e-8, 0.0], [0.0, -1e-8], [3e-9, -4e-9]])


@jax.jit
def _profile(law, scale, pressures, radii):
    """Everything the generic tests compare, for one law, in few compiled graphs."""
    pressure, radius = pressures[1], radii[1]
    curvature = scale * _GRID
    step = _FD_STEP * scale
    magnitudes = scale * _DIRECTIONAL_MAGNITUDES
    count = curvature.shape[0]
    # One evaluation of M and M' for the grid, its mirror, the FD neighbours, magnitudes.
    moments, tangents = _moment_and_tangent(
        law, jnp.concatenate([curvature, -curvature, curvature + step, curvature - step,
                              magnitudes]), pressure, radius)
    # One jax.hessian pass: the grid as vectors (k, 0), near-zero and oblique vectors.
    vectors = jnp.concatenate([
        jnp.stack([curvature, jnp.zeros_like(curvature)], axis=-1),
        scale * jnp.stack([_QUAD_TARGETS, jnp.zeros_like(_QUAD_TARGETS)], axis=-1),
        jnp.asarray(_NEAR_ZERO_VECTORS),
        magnitudes[:, None] * _DIRECTION])
    energies, gradients, hessians = _vector_derivatives(law, vectors, pressure, radius)
    targets = count + len(_QUAD_TARGETS)
    near_zero = targets + len(_NEAR_ZERO_VECTORS)
    # jit + vmap: a batch of laws (one per pressure) x radii x curvatures, against plain
    # broadcasting.
    laws = jax.vmap(lambda _: law)(pressures)
    looped = jax.vmap(jax.vmap(jax.vmap(
        lambda one_law, k, p, r: one_law.moment(k, p, r),
        in_axes=(None, 0, None, None)), in_axes=(None, None, None, 0)),
        in_axes=(0, None, 0, None))(laws, curvature[:7], pressures, radii)
    grid3 = (curvature[:7, None, None], pressures[:, None], radii)
    return dict(
        curvature=curvature,
        moment=moments[:count],
        mirrored=moments[count:2 * count],
        moment_plus=moments[2 * count:3 * count],
        moment_minus=moments[3 * count:4 * count],
        tangent=tangents[:count],
        magnitude_moment=moments[4 * count:],
        magnitude_tangent=tangents[4 * count:],
        energy=energies[:count],
        energy_slope=gradients[:count, 0],
        energy_cross_slope=gradients[:count, 1],
        energy_second=hessians[:count, 0, 0],
        quad_energy=energies[count:targets],
        vectors=vectors[targets:near_zero],
        near_zero_gradients=gradients[targets:near_zero],
        near_zero_hessians=hessians[targets:near_zero],
        oblique_gradients=gradients[near_zero:],
        oblique_hessians=hessians[near_zero:],
        initial_stiffness=law.initial_stiffness(pressure, radius),
        looped_moment=looped,
        broadcast_moment=law.moment(*grid3),
        broadcast_regime=law.regime(*grid3),
        broadcast_energy=law.energy_density(grid3[0] ** 2, *grid3[1:]),
        broadcast_stiffness=law.initial_stiffness(pressures[:, None], radii),
    )


@pytest.fixture(scope="module", params=list(LAW_CASES))
def profiled(request):
    law, stiffness, scale = LAW_CASES[request.param]
    pressures = PRESSURE * jnp.array([0.75, 1.0, 1.5])
    radii = RADIUS * jnp.array([0.8, 1.0, 1.2])
    profile = {key: np.asarray(value)
               for key, value in _profile(law, scale, pressures, radii).items()}
    return law, stiffness, scale, profile


def test_energy_derivative_is_moment(profiled):
    _, _, _, profile = profiled
    moment = profile["moment"]
    np.testing.assert_allclose(profile["energy_slope"], moment, rtol=1e-10,
                               atol=1e-13 * np.abs(moment).max())
    np.testing.assert_array_equal(profile["energy_cross_slope"], 0.0)


def test_energy_is_quadrature_of_moment(profiled):
    law, _, scale, profile = profiled
    breakpoints = []
    if isinstance(law, SplineLaw):
        knots = np.asarray(law.pivots(PRESSURE, RADIUS)[0])
        breakpoints = [float(law.linear_share) * knots[0]] + knots.tolist()
    elif isinstance(law, TensionFieldLaw):
        breakpoints = [WRINKLING_CURVATURE]
    for target, energy in zip(scale * _QUAD_TARGETS, profile["quad_energy"]):
        expected = _quad_energy(law, target, PRESSURE, RADIUS, breakpoints)
        assert energy == pytest.approx(expected, rel=1e-9)
    assert profile["energy"][0] == 0.0


def test_moment_is_odd_and_increasing(profiled):
    _, _, _, profile = profiled
    moment = profile["moment"]
    assert moment[0] == 0.0
    assert np.all(np.diff(moment[:_DENSE]) > 0)  # from 0 to 2x the characteristic curvature
    np.testing.assert_allclose(profile["mirrored"], -moment, rtol=1e-15, atol=0.0)


def test_tangent_matches_finite_differences_and_energy_hessian(profiled):
    _, _, scale, profile = profiled
    central = (profile["moment_plus"] - profile["moment_minus"]) / (2.0 * _FD_STEP * scale)
    # Central differences need |kappa| > step (the 2011 bending law has a |kappa|^3 term).
    usable = profile["curvature"] > 10.0 * _FD_STEP * scale
    # Rounding in M limits the differences to ~1e-8 of the initial slope; a spline knot
    # inside the stencil (jump in M'') to ~1e-6 relative.
    np.testing.assert_allclose(profile["tangent"][usable], central[usable], rtol=1e-5,
                               atol=1e-7 * profile["tangent"][0])
    np.testing.assert_allclose(profile["energy_second"], profile["tangent"], rtol=1e-8,
                               atol=1e-12 * profile["tangent"].max())


def test_hessian_at_and_near_zero(profiled):
    _, stiffness, _, profile = profiled
    assert float(profile["initial_stiffness"]) == pytest.approx(stiffness, rel=1e-12)
    assert profile["tangent"][0] == pytest.approx(stiffness, rel=1e-12)
    gradients, hessians = profile["near_zero_gradients"], profile["near_zero_hessians"]
    assert np.all(np.isfinite(hessians))
    # Exactly zero: zero gradient, Hessian EI0 * I.
    np.testing.assert_array_equal(gradients[0], np.zeros(2))
    np.testing.assert_allclose(hessians[0], stiffness * np.eye(2), rtol=1e-12, atol=0.0)
    # Near zero (|kappa| ~ 1e-8 1/m): consistent with the Hessian at zero.
    np.testing.assert_allclose(gradients[1:], stiffness * profile["vectors"][1:], rtol=1e-6)
    np.testing.assert_allclose(hessians[1:], np.broadcast_to(stiffness * np.eye(2), (3, 2, 2)),
                               rtol=1e-6, atol=1e-6 * stiffness)


def test_hessian_is_that_of_a_function_of_the_magnitude(profiled):
    """H = (M/|k|) (I - n n^T) + M'(|k|) n n^T, so every bending direction is alike."""
    _, _, scale, profile = profiled
    outer = np.outer(_DIRECTION, _DIRECTION)
    for index, magnitude in enumerate(scale * _DIRECTIONAL_MAGNITUDES):
        moment = profile["magnitude_moment"][index]
        tangent = profile["magnitude_tangent"][index]
        expected = moment / magnitude * (np.eye(2) - outer) + tangent * outer
        np.testing.assert_allclose(profile["oblique_hessians"][index], expected,
                                   rtol=1e-8, atol=1e-10 * np.abs(expected).max())
        np.testing.assert_allclose(profile["oblique_gradients"][index],
                                   moment * _DIRECTION, rtol=1e-10)


def test_jit_vmap_and_broadcasting(profiled):
    _, _, _, profile = profiled
    for key in ("broadcast_moment", "broadcast_energy", "broadcast_regime"):
        assert profile[key].shape == (7, 3, 3)
    assert profile["broadcast_regime"].dtype == np.int32
    assert profile["broadcast_stiffness"].shape == (3, 3)
    # looped is indexed (law/pressure, radius, curvature).
    np.testing.assert_allclose(np.transpose(profile["looped_moment"], (2, 0, 1)),
                               profile["broadcast_moment"], rtol=1e-13, atol=1e-14)


def test_laws_are_abstract_moment_laws():
    for law, _, _ in LAW_CASES.values():
        assert isinstance(law, AbstractMomentLaw)
    with pytest.raises(TypeError):
        AbstractMomentLaw()


# ------------------------------------------------------------------------------------------
# SplineLaw
# ------------------------------------------------------------------------------------------

_REFERENCE_PIVOT_CURVATURE = 0.02  # [1/m]
_REFERENCE_PIVOT_MOMENT = 4.0  # [N m]
_SPLINE_GRID = 4001
_C1_OFFSETS = np.array([-2.0, -1.0, 0.0, 1.0, 2.0])


@st.composite
def spline_setups(draw):
    pivot_count = 9
    steps = hnp.arrays(np.float64, pivot_count, elements=st.floats(0.05, 5.0))
    exponents = hnp.arrays(np.float64, pivot_count, elements=st.floats(0.3, 1.5))
    curvatures = np.cumsum(draw(steps)) * _REFERENCE_PIVOT_CURVATURE
    moments = np.cumsum(draw(steps)) * _REFERENCE_PIVOT_MOMENT
    if draw(st.booleans()):
        radius_exponents = (draw(hnp.arrays(np.float64, pivot_count,
                                            elements=st.floats(-1.0, 1.0))),
                            draw(hnp.arrays(np.float64, pivot_count,
                                            elements=st.floats(2.0, 4.0))))
    else:
        radius_exponents = None
    law = SplineLaw.from_pivots(curvatures, moments, PRESSURE, RADIUS,
                                curvature_exponent=draw(exponents),
                                moment_exponent=draw(exponents),
                                radius_exponents=radius_exponents,
                                residual_stiffness_ratio=draw(st.floats(1e-3, 0.1)),
                                linear_share=draw(st.sampled_from([0.0, 0.5])
                                                  | st.floats(0.0, 0.95)))
    pressure = PRESSURE * draw(st.sampled_from([0.5, 1.0, 2.0]))
    radius = RADIUS * draw(st.sampled_from([0.7, 1.0, 1.3]))
    return law, pressure, radius


@jax.jit
def _spline_profile(law, pressure, radius):
    """What the property test checks, for one spline law, in few compiled graphs."""
    knots, knot_moments = law.pivots(pressure, radius)
    grid = jnp.linspace(0.0, 2.0 * knots[-1], _SPLINE_GRID)
    points = jnp.concatenate([jnp.zeros(1), knots])
    step = 1e-5 * jnp.min(jnp.diff(points))
    points = jnp.concatenate([points, law.linear_share * knots[:1]])  # where M'' may jump
    around = (points + step * jnp.asarray(_C1_OFFSETS)[:, None]).ravel()
    targets = jnp.stack([0.5 * knots[0], knots[3], 0.5 * (knots[5] + knots[6]),
                         1.5 * knots[-1]])
    moments = law.moment(jnp.concatenate([grid, -grid, knots, around]), pressure, radius)
    count = _SPLINE_GRID

    def energy(k):
        return law.energy_density(k**2, pressure, radius)
    everywhere = jnp.concatenate([grid, targets])
    energies, slopes = jax.jvp(energy, (everywhere,), (jnp.ones_like(everywhere),))
    return dict(
        knots=knots, knot_moments=knot_moments,
        moment=moments[:count], mirrored=moments[count:2 * count],
        moment_at_knots=moments[2 * count:2 * count + knots.shape[0]],
        around=moments[2 * count + knots.shape[0]:].reshape(len(_C1_OFFSETS), -1),
        step=step,
        energy_slope=slopes[:count],
        targets=targets, target_energy=energies[count:],
        initial_stiffness=law.initial_stiffness(pressure, radius),
    )


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(spline_setups())
def test_spline_is_odd_monotone_c1_and_integrable(setup):
    law, pressure, radius = setup
    profile = {key: np.asarray(value)
               for key, value in _spline_profile(law, pressure, radius).items()}
    knots, knot_moments = profile["knots"], profile["knot_moments"]
    assert np.all(np.diff(knots) > 0) and np.all(np.diff(knot_moments) > 0)

    # Interpolates its pivots.
    np.testing.assert_allclose(profile["moment_at_knots"], knot_moments, rtol=1e-12)

    # Odd and strictly increasing out to 2x the last pivot.
    moment = profile["moment"]
    assert moment[0] == 0.0
    assert np.all(np.diff(moment) > 0)
    np.testing.assert_allclose(profile["mirrored"], -moment, rtol=1e-15, atol=0.0)

    # C1: one-sided second-order differences agree at 0 and at every pivot; a kink would
    # show as a jump of the order of the adjacent secants.
    points = np.concatenate([[0.0], knots])
    secants = np.diff(np.concatenate([[0.0], knot_moments])) / np.diff(points)
    local_slope = np.maximum(np.concatenate([[secants[0]], secants]),
                             np.concatenate([secants, [secants[-1]]]))
    local_slope = np.concatenate([local_slope, local_slope[:1]])  # k_0 = share * k_1
    far_left, left, centre, right, far_right = profile["around"]
    step = profile["step"]
    left_slope = (3.0 * centre - 4.0 * left + far_left) / (2.0 * step)
    right_slope = (-3.0 * centre + 4.0 * right - far_right) / (2.0 * step)
    assert np.all(np.abs(left_slope - right_slope) <= 1e-5 * local_slope)
    assert left_slope[0] == pytest.approx(float(profile["initial_stiffness"]), rel=1e-6)

    # The energy integrates the moment.
    np.testing.assert_allclose(profile["energy_slope"], moment, rtol=1e-10,
                               atol=1e-13 * moment.max())
    for target, energy in zip(profile["targets"], profile["target_energy"]):
        expected = _quad_energy(law, target, pressure, radius,
                                [float(law.linear_share) * knots[0], *knots])
        assert energy == pytest.approx(expected, rel=1e-9)


def test_spline_pivot_scaling_forms():
    curvatures = np.arange(1.0, 10.0) * 0.01
    moments = np.sqrt(np.arange(1.0, 10.0))
    exponents = np.linspace(0.5, 1.3, 9)
    paper = SplineLaw.from_pivots(curvatures, moments, PRESSURE, RADIUS,
                                  curvature_exponent=exponents, moment_exponent=0.8)
    # Equal exponents within a coordinate: every pivot is A (p r^3)^B (Breukels & Ockels).
    factor = 3.0 * 0.9**3
    _, scaled_moments = paper.pivots(3.0 * PRESSURE, 0.9 * RADIUS)
    np.testing.assert_allclose(scaled_moments, moments * factor**0.8, rtol=1e-12)
    separate = SplineLaw.from_pivots(curvatures, moments, PRESSURE, RADIUS,
                                     curvature_exponent=1.0, moment_exponent=1.0,
                                     radius_exponents=(0.0, 3.0))
    scaled_curvatures, scaled_moments = separate.pivots(3.0 * PRESSURE, 0.9 * RADIUS)
    np.testing.assert_allclose(scaled_curvatures, 3.0 * curvatures, rtol=1e-12)
    np.testing.assert_allclose(scaled_moments, factor * moments, rtol=1e-12)
    for law in (paper, separate):
        knots, knot_moments = law.pivots(PRESSURE, RADIUS)
        np.testing.assert_allclose(knots, curvatures, rtol=1e-12)
        np.testing.assert_allclose(knot_moments, moments, rtol=1e-12)


def test_spline_regimes_and_collinear_first_regime():
    curvatures = np.array([1.0, 2.0, 3.0, 5.0, 8.0, 12.0, 20.0, 40.0, 80.0]) * 0.01
    moments = np.array([1.0, 2.0, 3.0, 3.8, 4.4, 4.8, 5.0, 5.1, 5.15])
    law = SplineLaw.from_pivots(curvatures, moments, PRESSURE, RADIUS)
    assert float(law.initial_stiffness(PRESSURE, RADIUS)) == pytest.approx(100.0)
    # Collinear regime-1 pivots: exactly linear up to the second-to-last regime-1 pivot.
    inner = np.linspace(-0.02, 0.02, 41)
    probes = np.array([0.0, 0.03, 0.0301, 0.12, 0.1201, 2.0])
    tail = np.array([1.0, 2.0])
    curvature = jnp.asarray(np.concatenate([inner, probes, -probes, tail]))
    moment = np.asarray(_moment(law, curvature, PRESSURE, RADIUS))
    regime = np.asarray(_regime(law, curvature, PRESSURE, RADIUS))
    np.testing.assert_allclose(moment[:41], 100.0 * inner, rtol=1e-13, atol=1e-15)
    np.testing.assert_array_equal(regime[41:53], [0, 0, 1, 1, 2, 2] * 2)
    # Beyond the last pivot: linear with the residual slope 1/k = 1/(0.01 d0) + 1/(3 d_last).
    residual = 1.0 / (1.0 / (0.01 * 100.0) + 1.0 / (3.0 * 0.05 / 0.4))
    assert moment[-1] - moment[-2] == pytest.approx(residual, rel=1e-12)


def test_spline_other_pivot_counts():
    law = SplineLaw.from_pivots([0.01, 0.02, 0.05, 0.1, 0.3], [1.0, 1.5, 2.0, 2.2, 2.3],
                                PRESSURE, RADIUS, pivots_per_regime=(1, 2, 2))
    probes = jnp.array([0.0, 0.005, 0.02, 0.05, 0.3])
    moment, tangent, second, regime = _curve(law, probes, PRESSURE, RADIUS)
    np.testing.assert_array_equal(regime, [0, 0, 1, 1, 2])
    np.testing.assert_allclose(moment[3:], [2.0, 2.3], rtol=1e-12)
    np.testing.assert_allclose(second, tangent, rtol=1e-10)
    assert float(tangent[0]) == pytest.approx(float(law.initial_stiffness(PRESSURE, RADIUS)))


def test_spline_linear_share_first_piece_by_hand():
    """The first piece M = a k + b max(k - k_0, 0)^3: at share 0 the odd cubic of the paper
    form; at 0.6 exactly linear up to k_0, C2 there, meeting M_1 with the knot slope."""
    curvatures, moments = _SHARE_PIVOTS
    k1 = curvatures[0]
    probes = np.concatenate([np.linspace(0.0, k1, 41), [0.3, 1.0]])
    for share in (0.0, 0.6, 0.95):
        law = eqx.tree_at(lambda old: old.linear_share, _SHARE_LAW, jnp.asarray(share))
        a, b, k0 = _first_piece(curvatures, moments, share)
        moment, tangent, second, regime = (np.asarray(v) for v in _curve(
            law, jnp.asarray(probes), PRESSURE, RADIUS))
        inner = probes[:41]
        expected = a * inner + b * np.maximum(inner - k0, 0.0) ** 3
        np.testing.assert_allclose(moment[:41], expected, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(tangent[:41], a + 3 * b * np.maximum(inner - k0, 0.0) ** 2,
                                   rtol=1e-10)
        assert moment[40] == pytest.approx(moments[0], rel=1e-13)
        assert tangent[40] == pytest.approx(_first_pivot_slope(curvatures, moments), rel=1e-10)
        np.testing.assert_allclose(second, tangent, rtol=1e-9)  # energy Hessian = tangent
        assert np.all(np.diff(moment) > 0)
        np.testing.assert_array_equal(regime, [0] * 41 + [1, 2])
    assert _first_piece(curvatures, moments, 0.0)[0] == pytest.approx(
        0.5 * (3.0 * moments[0] / k1 - _first_pivot_slope(curvatures, moments)), rel=1e-14)
    # Towards share 1 the law is linear up to the first pivot: a -> M_1 / k_1.
    assert _first_piece(curvatures, moments, 0.95)[0] == pytest.approx(
        moments[0] / k1, rel=0.02)


def test_spline_linear_share_derivatives_at_its_null():
    """d/d(share) at share = 0 (the diagnosis' null) is finite and matches a forward
    difference, also at and near zero curvature (where the square root is guarded)."""
    curvatures = jnp.array([0.0, 1e-9, 0.01, 0.04, 0.3])

    @jax.jit
    def energy_and_moment(share):
        law = eqx.tree_at(lambda old: old.linear_share, _SHARE_LAW, share)
        return (law.energy_density(curvatures**2, PRESSURE, RADIUS),
                law.moment(curvatures, PRESSURE, RADIUS))

    derivatives = jax.jacfwd(energy_and_moment)(jnp.asarray(0.0))
    reverse = jax.jacrev(energy_and_moment)(jnp.asarray(0.0))
    step = 1e-7
    forward = [(plus - zero) / step for plus, zero in
               zip(energy_and_moment(jnp.asarray(step)), energy_and_moment(jnp.asarray(0.0)))]
    for exact, backward, difference in zip(derivatives, reverse, forward):
        assert np.all(np.isfinite(exact)) and np.all(np.isfinite(backward))
        np.testing.assert_allclose(exact, backward, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(exact, difference, rtol=1e-5,
                                   atol=1e-6 * float(np.abs(exact).max()))


@pytest.mark.parametrize("share", [1.0, -0.1])
def test_spline_rejects_linear_share_outside_range(share):
    with pytest.raises(ValueError, match="linear_share must lie in"):
        SplineLaw.from_pivots(*_SHARE_PIVOTS, PRESSURE, RADIUS, pivots_per_regime=(1, 1, 1),
                              linear_share=share)


@pytest.mark.parametrize("curvatures, moments, message", [
    ([1, 2, 3, 4, 4, 6, 7, 8, 9], np.arange(1.0, 10.0), "strictly increasing"),
    ([1, 2, 3, 5, 4, 6, 7, 8, 9], np.arange(1.0, 10.0), "strictly increasing"),
    (np.arange(1.0, 10.0), [1, 2, 3, 4, 5, 6, 7, 8, 7], "strictly increasing"),
    ([0, 2, 3, 4, 5, 6, 7, 8, 9], np.arange(1.0, 10.0), "positive"),
    (np.arange(1.0, 10.0), [-1, 2, 3, 4, 5, 6, 7, 8, 9], "positive"),
    (np.arange(1.0, 9.0), np.arange(1.0, 9.0), "shape"),
])
def test_from_pivots_rejects_bad_pivots(curvatures, moments, message):
    with pytest.raises(ValueError, match=message):
        SplineLaw.from_pivots(curvatures, moments, PRESSURE, RADIUS)


def test_from_tension_field_rejects_bad_options():
    with pytest.raises(ValueError, match="form"):
        SplineLaw.from_tension_field(WALL_MODULUS, PRESSURE, RADIUS, form="scaled")
    with pytest.raises(ValueError, match="collapse_fraction"):
        SplineLaw.from_tension_field(WALL_MODULUS, PRESSURE, RADIUS, collapse_fraction=0.4)
    with pytest.raises(ValueError, match="collapsed_extent"):
        SplineLaw.from_tension_field(WALL_MODULUS, PRESSURE, RADIUS, collapsed_extent=1.0)


def test_constructor_rejects_inconsistent_fields():
    ones = np.ones(9)
    with pytest.raises(ValueError, match="shape"):
        SplineLaw(ones, ones, ones, ones, pivots_per_regime=(2, 3, 3))
    with pytest.raises(ValueError, match="both"):
        SplineLaw(ones, ones, ones, ones, curvature_radius_exponent=ones)
    with pytest.raises(ValueError, match="positive integers"):
        SplineLaw(ones, ones, ones, ones, pivots_per_regime=(0, 4, 5))


def test_from_tension_field_samples_the_tension_field_law():
    tension_field = TensionFieldLaw(WALL_MODULUS)
    law = SplineLaw.from_tension_field(WALL_MODULUS, PRESSURE, RADIUS)
    knots, knot_moments = law.pivots(PRESSURE, RADIUS)
    curvature = jnp.concatenate([knots, jnp.linspace(0.0, knots[-1], 2001)])
    spline_moment = np.asarray(_moment(law, curvature, PRESSURE, RADIUS))
    tension_field_moment = np.asarray(_moment(tension_field, curvature, PRESSURE, RADIUS))
    np.testing.assert_allclose(knot_moments, tension_field_moment[:9], rtol=1e-12)
    np.testing.assert_allclose(spline_moment[:9], knot_moments, rtol=1e-12)
    # Regime 1 ends at the wrinkling onset (M_w), regime 2 at 0.95 M_c.
    assert float(knots[2]) == pytest.approx(WRINKLING_CURVATURE, rel=1e-12)
    assert float(knot_moments[2]) == pytest.approx(0.5 * COLLAPSE_MOMENT, rel=1e-12)
    assert float(knot_moments[5]) == pytest.approx(0.95 * COLLAPSE_MOMENT, rel=1e-12)
    assert float(knots[8]) == pytest.approx(10.0 * float(knots[5]), rel=1e-12)
    # Between the pivots the spline stays close to the curve it samples.
    error = np.abs(spline_moment - tension_field_moment).max()
    assert error < 0.05 * COLLAPSE_MOMENT


@pytest.mark.parametrize("pressure_factor, radius_factor", [(2.0, 1.0), (1.0, 2.0),
                                                             (0.6, 1.4)])
def test_from_tension_field_scaling(pressure_factor, radius_factor):
    pressure, radius = PRESSURE * pressure_factor, RADIUS * radius_factor
    tension_field = TensionFieldLaw(WALL_MODULUS)
    separate = SplineLaw.from_tension_field(WALL_MODULUS, PRESSURE, RADIUS)
    reference_curvatures, reference_moments = separate.pivots(PRESSURE, RADIUS)
    curvatures, moments = separate.pivots(pressure, radius)
    # Exact scaling of the tension-field law: kappa ~ p r^0, M ~ p r^3.
    np.testing.assert_allclose(curvatures, pressure_factor * reference_curvatures,
                               rtol=1e-12)
    np.testing.assert_allclose(moments, pressure_factor * radius_factor**3
                               * reference_moments, rtol=1e-12)
    np.testing.assert_allclose(moments, _moment(tension_field, curvatures, pressure, radius),
                               rtol=1e-12)
    # The paper form scales the curvatures with (p r^3)^1: right in p, wrong in r.
    paper = SplineLaw.from_tension_field(WALL_MODULUS, PRESSURE, RADIUS, form="paper")
    paper_curvatures, paper_moments = paper.pivots(pressure, radius)
    np.testing.assert_allclose(paper_curvatures, pressure_factor * radius_factor**3
                               * reference_curvatures, rtol=1e-12)
    np.testing.assert_allclose(paper_moments, moments, rtol=1e-12)


def test_spline_gradients_with_respect_to_parameters():
    """Calibration differentiates through the law's fields and through from_tension_field;
    one vmapped value-and-gradient call gives the gradient and its finite differences."""
    law = SplineLaw.from_tension_field(WALL_MODULUS, PRESSURE, RADIUS)
    curvature = jnp.array([0.3, 3.0, 20.0]) * WRINKLING_CURVATURE

    def total_energy(scales):
        changed = eqx.tree_at(lambda m: m.curvature_scale, law, scales)
        return jnp.sum(changed.energy_density(curvature**2, PRESSURE, RADIUS))

    scales = law.curvature_scale
    steps = 1e-6 * scales
    batch = jnp.concatenate([scales[None], scales + jnp.diag(steps),
                             scales - jnp.diag(steps)])
    values, gradients = jax.jit(jax.vmap(jax.value_and_grad(total_energy)))(batch)
    count = scales.shape[0]
    central = (values[1:count + 1] - values[count + 1:]) / (2.0 * steps)
    np.testing.assert_allclose(gradients[0], central, rtol=1e-5, atol=1e-9)

    def moment_of_wall(wall_modulus):
        spline = SplineLaw.from_tension_field(wall_modulus, PRESSURE, RADIUS)
        return spline.moment(2.0 * WRINKLING_CURVATURE, PRESSURE, RADIUS)

    step = 1e-5 * WALL_MODULUS
    walls = WALL_MODULUS + step * jnp.array([0.0, 1.0, -1.0])
    values, derivatives = jax.jit(jax.vmap(
        lambda wall: jax.jvp(moment_of_wall, (wall,), (jnp.ones_like(wall),))))(walls)
    assert float(derivatives[0]) == pytest.approx(
        float(values[1] - values[2]) / (2.0 * step), rel=1e-6)
    tension_field = TensionFieldLaw(WALL_MODULUS)
    assert float(values[0]) == pytest.approx(
        float(_moment(tension_field, 2.0 * WRINKLING_CURVATURE, PRESSURE, RADIUS)), rel=0.05)


# ------------------------------------------------------------------------------------------
# TensionFieldLaw
# ------------------------------------------------------------------------------------------


def _tension_field_parametric(angle):
    """kappa(a), M(a), dM/dkappa(a) of docs/physics.md, section 2.3, in numpy."""
    g = np.sin(angle) - angle * np.cos(angle)
    numerator = angle - np.sin(angle) * np.cos(angle)
    curvature = math.pi * WRINKLING_CURVATURE / g
    moment = 0.5 * COLLAPSE_MOMENT * numerator / g
    moment_rate = 0.5 * COLLAPSE_MOMENT * (2.0 * np.sin(angle) ** 2 * g
                                           - numerator * angle * np.sin(angle)) / g**2
    curvature_rate = -math.pi * WRINKLING_CURVATURE * angle * np.sin(angle) / g**2
    return curvature, moment, moment_rate / curvature_rate


@jax.jit
def _curve(law, curvature, pressure, radius):
    """M, dM/dkappa, d^2/dkappa^2 W(kappa^2) (by jax.hessian) and regime on a 1-D array."""
    moment, tangent = _moment_and_tangent(law, curvature, pressure, radius)
    vectors = jnp.stack([curvature, jnp.zeros_like(curvature)], axis=-1)
    _, _, hessians = _vector_derivatives(law, vectors, pressure, radius)
    return moment, tangent, hessians[:, 0, 0], law.regime(curvature, pressure, radius)


_ANGLES = np.linspace(0.3, math.pi - 0.01, 60)
_ONSET_PROBES = np.array([1.0, 1.0 + 1e-9, 1.0 - 1e-9, 1.0 - 1e-7, 1.0 + 1e-7])
_ASYMPTOTIC_PROBES = np.array([1e4, 1e6, 1e9])
_REGIME_PROBES = np.array([0.0, 0.5, 1.0, 2.0, 20.0, 40.0, 1e4])


@pytest.fixture(scope="module")
def tension_field_curve():
    """One compiled evaluation of TensionFieldLaw on all probes of this section."""
    law = TensionFieldLaw(WALL_MODULUS)
    parametric = _tension_field_parametric(_ANGLES)
    probes = [parametric[0], WRINKLING_CURVATURE * _ONSET_PROBES,
              WRINKLING_CURVATURE * _ASYMPTOTIC_PROBES, WRINKLING_CURVATURE * _REGIME_PROBES,
              -WRINKLING_CURVATURE * _REGIME_PROBES]
    results = [np.asarray(x) for x in _curve(law, jnp.asarray(np.concatenate(probes)),
                                              PRESSURE, RADIUS)]
    splits = np.cumsum([len(p) for p in probes])[:-1]
    return parametric, [np.split(r, splits) for r in results]


def test_tension_field_matches_parametric_solution(tension_field_curve):
    (curvature, moment, tangent), results = tension_field_curve
    np.testing.assert_allclose(results[0][0], moment, rtol=1e-12)
    np.testing.assert_allclose(results[1][0], tangent, rtol=1e-9)
    np.testing.assert_allclose(results[2][0], tangent, rtol=1e-8)  # W'' by jax.hessian


def test_tension_field_comer_levy_limits(tension_field_curve):
    _, results = tension_field_curve
    onset_moment, onset_tangent = results[0][1], results[1][1]
    # M_w = pi p r^3 / 2 at kappa_w = p / (2 E t), continuous on both sides.
    assert onset_moment[0] == pytest.approx(0.5 * COLLAPSE_MOMENT, rel=1e-14)
    np.testing.assert_allclose(onset_moment[1:3], 0.5 * COLLAPSE_MOMENT, rtol=1e-8)
    # The slope is continuous (= EI) through the onset.
    np.testing.assert_allclose(onset_tangent[3:], BENDING_STIFFNESS, rtol=1e-3)
    # M tends to M_c slowly: M_c - M ~ M_c (3 pi kappa_w / kappa)^(2/3) / 10, with a
    # relative correction of the order of (3 pi kappa_w / kappa)^(2/3).
    far_moment = results[0][2]
    deficit = 1.0 - far_moment / COLLAPSE_MOMENT
    asymptote = (3.0 * math.pi / _ASYMPTOTIC_PROBES) ** (2.0 / 3.0) / 10.0
    np.testing.assert_allclose(deficit / asymptote, 1.0, rtol=0.05)
    np.testing.assert_allclose(deficit[1:] / asymptote[1:], 1.0, rtol=2e-3)
    np.testing.assert_allclose(deficit[2:] / asymptote[2:], 1.0, rtol=1e-4)
    assert 0.0 < deficit[0] < 2e-3  # within 0.2 % of M_c at 1e4 kappa_w


def test_tension_field_regimes(tension_field_curve):
    _, results = tension_field_curve
    np.testing.assert_array_equal(results[3][1], [0, 1, 0, 0, 1])
    np.testing.assert_array_equal(results[3][3], [0, 0, 0, 1, 1, 2, 2])
    np.testing.assert_array_equal(results[3][4], [0, 0, 0, 1, 1, 2, 2])


def test_tension_field_wrinkling_onset_independent_of_radius():
    law = TensionFieldLaw(WALL_MODULUS)
    radii = jnp.array([0.03, 0.075, 0.15])
    curvature = WRINKLING_CURVATURE * jnp.array([1.0 - 1e-9, 1.0 + 1e-9, 1.0])
    np.testing.assert_array_equal(_regime(law, curvature[:, None], PRESSURE, radii),
                                  [[0, 0, 0], [1, 1, 1], [0, 0, 0]])
    np.testing.assert_allclose(_moment(law, curvature[2], PRESSURE, radii),
                               0.5 * math.pi * PRESSURE * radii**3, rtol=1e-14)


def test_tension_field_residual_stiffness_adds_linear_term():
    plain = TensionFieldLaw(WALL_MODULUS)
    stiffened = TensionFieldLaw(WALL_MODULUS, residual_stiffness_ratio=0.02)
    curvature = WRINKLING_CURVATURE * jnp.array([0.5, 3.0, 100.0])
    np.testing.assert_allclose(
        _moment(stiffened, curvature, PRESSURE, RADIUS) - _moment(plain, curvature, PRESSURE,
                                                                     RADIUS),
        0.02 * BENDING_STIFFNESS * curvature, rtol=1e-12)


def test_tension_field_parameter_gradient():
    def moment(wall_modulus):
        return TensionFieldLaw(wall_modulus).moment(5.0 * WRINKLING_CURVATURE, PRESSURE,
                                                    RADIUS)
    step = 1e-5 * WALL_MODULUS
    walls = WALL_MODULUS + step * jnp.array([0.0, 1.0, -1.0])
    values, gradients = jax.jit(jax.vmap(jax.value_and_grad(moment)))(walls)
    assert float(gradients[0]) == pytest.approx(float(values[1] - values[2]) / (2.0 * step),
                                                 rel=1e-7)


# ------------------------------------------------------------------------------------------
# Breukels (2011) empirical laws
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("pressure_bar, stiffness", [(0.2, 212.0), (0.4, 269.0)])
def test_empirical_bending_initial_stiffness(pressure_bar, stiffness):
    law = EmpiricalBendingLaw2011()
    value = float(law.initial_stiffness(pressure_bar * 1e5, 0.075))
    assert value == pytest.approx(stiffness, rel=3e-3)


def test_empirical_bending_plateau_and_regimes():
    law = EmpiricalBendingLaw2011()
    pressure_bar = 0.2
    maximum = (6582.82 * RADIUS - 272.43) * pressure_bar**2 + 40852.38 * RADIUS**3 + 14.31
    scale = maximum / _BENDING_2011_STIFFNESS
    curvature = scale * jnp.array([0.0, 0.5, math.log(2.0) * 1.001, 2.0,
                                   math.log(20.0) * 1.001, 50.0])
    moment = _moment(law, curvature, PRESSURE, RADIUS)
    np.testing.assert_allclose(moment, maximum * -np.expm1(-np.asarray(curvature) / scale),
                               rtol=1e-13)
    assert float(moment[-1]) == pytest.approx(maximum, rel=1e-15)
    np.testing.assert_array_equal(_regime(law, curvature, PRESSURE, RADIUS),
                                  [0, 0, 1, 1, 2, 2])
    energy = _energy(law, curvature, PRESSURE, RADIUS)
    closed = maximum * (curvature - scale * -jnp.expm1(-curvature / scale))
    np.testing.assert_allclose(energy[2:], closed[2:], rtol=1e-12)


def test_empirical_torsion_closed_form():
    law = EmpiricalTorsionLaw2011()
    twist_rate = jnp.array([-3.0, 0.1, 1.0, 5.0])
    np.testing.assert_allclose(_moment(law, twist_rate, PRESSURE, RADIUS),
                               _TORSION_TORQUE * np.arctan(_TORSION_TWIST * twist_rate),
                               rtol=1e-13)
    c = _TORSION_TWIST
    closed = _TORSION_TORQUE * (twist_rate * jnp.arctan(c * twist_rate)
                                - jnp.log1p(c**2 * twist_rate**2) / (2.0 * c))
    np.testing.assert_allclose(_energy(law, twist_rate, PRESSURE, RADIUS), closed,
                               rtol=1e-12)
    np.testing.assert_array_equal(_regime(law, twist_rate, PRESSURE, RADIUS), [0, 0, 0, 0])


def test_linear_law():
    law = LinearLaw(jnp.array([100.0, 200.0]))
    curvature = jnp.array([[0.5], [-1.0]])
    np.testing.assert_array_equal(_moment(law, curvature, PRESSURE, RADIUS),
                                  [[50.0, 100.0], [-100.0, -200.0]])
    np.testing.assert_array_equal(_energy(law, curvature, PRESSURE, RADIUS),
                                  [[12.5, 25.0], [50.0, 100.0]])
    assert _regime(law, curvature, PRESSURE, RADIUS).shape == (2, 2)
    assert _moment(LinearLaw(3), 2.0, PRESSURE, RADIUS) == 6.0  # integer stiffness is fine
