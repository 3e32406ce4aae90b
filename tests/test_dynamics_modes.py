"""Natural modes (jt.modes) against closed forms: Euler-Bernoulli cantilever bending and
torsion as segments are added, the beaded taut string, and a frequency's gradient."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxtube as jt
from tests.helpers import central_difference

BENDING_ROOTS = np.array([1.8751, 4.6941, 7.8548])  # beta_i L of a clamped-free beam


def _weightless_cantilever(segments, radius, stiffness=2.0, torsion=1.0, mass=1.0):
    structure, params = jt.cantilever(1.0, radius, 1e4, segments, jt.LinearLaw(stiffness),
                                      jt.LinearLaw(torsion), mass_per_length=mass)
    return structure, eqx.tree_at(lambda p: p.gravity, params, jnp.zeros(3))


def _bending_errors(segments):
    structure, params = _weightless_cantilever(segments, 1e-3)
    modes = jt.modes(structure, params, jt.equilibrium(structure, params), count=6)
    omega = np.asarray(modes.angular_frequency)
    # Bending comes in degenerate pairs (two planes) for a round, straight tube.
    np.testing.assert_allclose(omega[0::2], omega[1::2], rtol=1e-7)
    reference = BENDING_ROOTS**2 * np.sqrt(2.0 / 1.0)
    return omega[0::2] / reference - 1.0


def test_cantilever_bending_converges_to_euler_bernoulli_at_second_order():
    coarse, fine = _bending_errors(4), _bending_errors(8)
    order = np.log2(np.abs(coarse) / np.abs(fine))
    assert np.all((order > 1.8) & (order < 2.2)), order
    assert np.all(np.abs(fine) < [0.01, 0.03, 0.05]), fine


def test_cantilever_torsion_frequencies():
    """A thin-walled tube twisting: omega_k = (2k - 1) pi / (2 L) sqrt(GJ / (mu r^2)); the
    torsion modes are those that move no node (the segments spin about the axis)."""
    radius, torsion, mass = 0.05, 1.0, 1.0
    structure, params = _weightless_cantilever(8, radius, torsion=torsion, mass=mass)
    modes = jt.modes(structure, params, jt.equilibrium(structure, params))
    moved = np.max(np.abs(np.asarray(modes.node_displacement)), axis=(1, 2))
    twist = np.asarray(modes.angular_frequency)[moved < 1e-9 * moved.max()]
    reference = (2 * np.arange(1, 3) - 1) * np.pi / 2 * np.sqrt(torsion / (mass * radius**2))
    errors = twist[:2] / reference - 1.0  # -0.16 %, -1.4 % at 8 segments
    assert np.all(np.abs(errors) < [0.005, 0.02]), errors
    assert abs(errors[0]) < abs(errors[1])


def test_beaded_string_frequencies_are_exact():
    """Three masses on four taut tension-only lines between fixed points: transverse
    omega_j = 2 sqrt(T / (m a)) sin(j pi / 8) (two polarisations), longitudinal
    2 sqrt(k / m) sin(j pi / 8) (Rayleigh's beaded string; exact for the discrete model)."""
    spacing, mass, stiffness, rest = 0.5, 0.2, 400.0, 0.45
    names = ["a", "p1", "p2", "p3", "b"]
    points = [jt.FixedPoint("a", [0.0, 0, 0])]
    points += [jt.PointNode(f"p{k}", [k * spacing, 0, 0], mass=mass) for k in (1, 2, 3)]
    points += [jt.FixedPoint("b", [4 * spacing, 0, 0])]
    lines = [jt.Line(names[k], names[k + 1], stiffness, rest) for k in range(4)]
    structure, params = jt.build_structure([], [], points=points, lines=lines,
                                           gravity=(0.0, 0.0, 0.0))
    modes = jt.modes(structure, params, jt.equilibrium(structure, params))
    tension = stiffness * (spacing - rest)
    sines = np.sin(np.arange(1, 4) * np.pi / 8)
    transverse = np.repeat(2 * np.sqrt(tension / (mass * spacing)) * sines, 2)
    longitudinal = 2 * np.sqrt(stiffness / mass) * sines
    expected = np.sort(np.concatenate([transverse, longitudinal]))
    np.testing.assert_allclose(np.asarray(modes.angular_frequency), expected, rtol=1e-8)
    assert not np.any(np.asarray(modes.zero_frequency))


@pytest.mark.slow  # the gradient's compilation: ~3 min on a loaded 2-core machine
def test_frequency_gradient_wrt_pressure_matches_central_differences():
    """Breukels' empirical laws (pressure-dependent), self-weight: the first frequency's
    derivative through the equilibrium and the eigenproblem."""

    structure, params = jt.cantilever(1.0, 0.075, 3e4, 2, jt.EmpiricalBendingLaw2011(),
                                      jt.EmpiricalTorsionLaw2011(), mass_per_length=0.3)

    def first_frequency(pressure):
        pressed = eqx.tree_at(lambda p: p.pressure, params, jnp.reshape(pressure, (1,)))
        return jt.modes(structure, pressed, jt.equilibrium(structure, pressed),
                        count=2).frequency[0]

    # One compiled program (value and gradient) serves the derivative and the differences.
    value_and_gradient = jax.jit(jax.value_and_grad(first_frequency))
    pressure = 3e4
    derivative = value_and_gradient(pressure)[1]
    reference = central_difference(lambda p: float(value_and_gradient(p)[0]), pressure, 1e-5)
    assert abs(reference) > 1e-6
    np.testing.assert_allclose(derivative, reference, rtol=1e-5)
