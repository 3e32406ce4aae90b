"""Time integration (jt.simulate_dynamics): the large-amplitude pendulum against the
elliptic-integral period at second order, energy over thousands of steps, a damped response
settling on the static equilibrium, modal frequency against the response, the gradient of
the peak tip displacement, and a line going slack."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.special import ellipk

import jaxtube as jt
from tests.helpers import central_difference

AMPLITUDE = np.radians(60.0)
RADIUS = 0.05
GRAVITY = 9.81


def _pendulum():
    """One rigid segment (1 m, r = 5 cm, 1 kg/m) pinned at its top, released at 60 degrees
    from the vertical."""
    tip = [np.sin(AMPLITUDE), 0.0, -np.cos(AMPLITUDE)]
    tube = jt.straight_tube("tube", [0.0, 0, 0], tip, 1, RADIUS, 1e4, jt.LinearLaw(1.0),
                            mass_per_length=1.0)
    return jt.build_structure([tube], [jt.Support("tube:0", "pinned")])


def _period_of_first_return(time, x, period):
    """Time of the first maximum of ``x`` after half a period (parabola through three)."""
    start = int(np.searchsorted(time, 0.5 * period))
    i = start + int(np.argmax(x[start: int(np.searchsorted(time, 1.5 * period))]))
    y0, y1, y2 = x[i - 1], x[i], x[i + 1]
    return time[i] + 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2) * (time[1] - time[0])


def test_pendulum_period_second_order_and_energy():
    """Physical pendulum: T = 4 K(sin^2(theta0 / 2)) / omega0 with omega0^2 = m g (L / 2) /
    I_pivot, I_pivot = m (L^2 / 3 + r^2 / 2) (7.3 % above the small-angle period at 60
    degrees). Over 3000 undamped steps the energy oscillates at O(h^2), does not grow, and
    decays slowly (the velocity projection), at third order in h."""
    structure, params = _pendulum()
    omega0 = np.sqrt(GRAVITY * 0.5 / (1 / 3 + RADIUS**2 / 2))
    period = 4 * ellipk(np.sin(AMPLITUDE / 2) ** 2) / omega0
    errors, swings, decay = [], [], []
    for step in (period / 60, period / 120):
        history = jt.simulate_dynamics(structure, params, step, 3000)
        assert bool(np.all(history.converged))
        time = np.asarray(history.time)
        x = np.asarray(history.node_position[:, 1, 0])
        errors.append(_period_of_first_return(time, x, period) / period - 1.0)
        energy = np.asarray(history.kinetic_energy + history.potential_energy)
        early, late = np.ptp(energy[:300]), np.ptp(energy[-300:])
        assert late < 2.0 * early, (early, late)  # bounded: no growth over 3000 steps
        swings.append(early)
        decay.append((energy[0] - energy[-1]) / (time[-1] / period))  # [J per period]
    assert abs(errors[0]) < 3e-3, errors
    assert 1.8 < np.log2(abs(errors[0]) / abs(errors[1])) < 2.2, errors
    assert 1.8 < np.log2(swings[0] / swings[1]) < 3.0, swings
    assert decay[1] >= 0.0 and np.log2(decay[0] / decay[1]) > 2.5, decay
    assert decay[1] < 1e-4 * abs(energy[0]), decay  # per period, at T / 120


# One cantilever for the remaining tests (one compiled program): Breukels' empirical laws,
# r = 75 mm, 1 m, self-weight, a sudden tip load from its static equilibrium.
STEPS, STEP = 400, 2e-3  # 12 periods of the first mode, 34 steps a period


def _cantilever(pressure=3e4):
    return jt.cantilever(1.0, 0.075, pressure, 3, jt.EmpiricalBendingLaw2011(),
                         jt.EmpiricalTorsionLaw2011(), mass_per_length=0.3)


def _respond(pressure, tip_load, step, damping=jt.Damping()):
    structure, params = _cantilever(pressure)
    static = jt.equilibrium(structure, params)
    load = jt.dynamic_load(structure, params, {"tube:end": [0.0, 0.0, -tip_load]},
                           jt.StepFunction())
    history = jt.simulate_dynamics(structure, params, step, STEPS, initial=static,
                                   loads=(load,), damping=damping)
    return structure, params, static, history


def test_small_response_oscillates_at_the_first_modal_frequency():
    structure, params = _cantilever()
    static = jt.equilibrium(structure, params)
    frequency = float(jt.modes(structure, params, static, count=1).frequency[0])
    _, _, _, history = _respond(3e4, 0.05, STEP)
    assert bool(np.all(history.converged))
    tip = np.asarray(history.node_position[:, -1, 2])
    tip = tip - 0.5 * (tip.max() + tip.min())
    time = np.asarray(history.time)
    ups = np.flatnonzero((tip[:-1] < 0) & (tip[1:] >= 0))
    crossings = time[ups] - tip[ups] / (tip[ups + 1] - tip[ups]) * (time[1] - time[0])
    measured = (len(crossings) - 1) / (crossings[-1] - crossings[0])
    assert len(crossings) >= 8
    # The average-acceleration rule's own period elongation: omega_h h = 2 atan(omega h / 2).
    omega_step = 2 * np.pi * frequency * (time[1] - time[0])
    discrete = frequency * 2 * np.arctan(omega_step / 2) / omega_step
    np.testing.assert_allclose(measured, discrete, rtol=2e-3)


def test_damped_response_settles_on_the_static_equilibrium():
    structure, params, _, history = _respond(
        3e4, 2.0, STEP, jt.Damping(mass_proportional=60.0, stiffness_proportional=1e-3))
    assert bool(np.all(history.converged))
    loaded = eqx.tree_at(lambda p: p.node_force, params,
                         params.node_force.at[structure.node_id("tube:end")].add(
                             jnp.array([0.0, 0.0, -2.0])))
    static = jt.equilibrium(structure, loaded)
    np.testing.assert_allclose(history.node_position[-1], static.node_position, atol=1e-6)
    assert float(history.kinetic_energy[-1]) < 1e-9


@pytest.mark.slow  # the gradient's compilation: ~3 min on a loaded 2-core machine
def test_peak_tip_displacement_gradient_wrt_pressure():
    def peak(pressure):
        _, _, static, history = _respond(pressure, 2.0, STEP)
        return jnp.max(static.node_position[-1, 2] - history.node_position[:, -1, 2])

    # The value-and-gradient programs serve the derivative and, through their value,
    # the central differences (a separate primal program would compile the history again).
    value_and_gradient = jax.value_and_grad(peak)
    pressure = 3e4
    derivative = value_and_gradient(pressure)[1]
    reference = central_difference(lambda p: float(value_and_gradient(p)[0]), pressure, 1e-5)
    assert abs(reference) > 1e-9
    np.testing.assert_allclose(derivative, reference, rtol=1e-4)


def test_a_line_going_slack_does_not_break_the_step():
    """A 1 kg mass on a 1 m line from a fixed point, released 5 cm above the taut length:
    it falls freely, the line snaps taut and throws it back up, slack again."""
    points = [jt.FixedPoint("anchor", [0.0, 0, 0]), jt.PointNode("bob", [0.0, 0, -1.0],
                                                                 mass=1.0)]
    structure, params = jt.build_structure(
        [], [], points=points, lines=[jt.Line("anchor", "bob", 2000.0, 1.0)])
    static = jt.equilibrium(structure, params)
    raised = eqx.tree_at(lambda s: s.state["point_position"], static,
                         static.state["point_position"].at[1, 2].set(-0.95))
    history = jt.simulate_dynamics(structure, params, 2e-3, 300, initial=raised)
    assert bool(np.all(history.converged))
    length = np.asarray(history.line_length[:, 0])
    slack, taut = length < 1.0 - 1e-3, length > 1.0 + 1e-3
    changes = np.count_nonzero(np.diff(slack.astype(int)) != 0)
    assert slack[0] and taut.any() and changes >= 2, changes
    # Free fall while slack: z = -0.95 - g t^2 / 2 until the line is taut.
    time = np.asarray(history.time)
    falling = time < np.sqrt(2 * 0.04 / GRAVITY)
    np.testing.assert_allclose(history.node_position[falling, 1, 2],
                               -0.95 - 0.5 * GRAVITY * time[falling] ** 2, atol=1e-9)


def test_step_hessian_blocks_and_factors_equal_autodiff():
    """The Hessian blocks each implicit step adds to the static Lagrangian's
    (``jaxtube._dynamics.step_system``: the centroid ties' curvature, inertia, joint damping;
    the static blocks are checked in tests/test_solver.py) equal the autodiff Hessian of the
    incremental potential plus multipliers times ties, and the step's factored constraint
    Jacobian ``C_z + C_w G^{-1} F`` equals the autodiff Jacobian of the constraints and ties,
    at a state with large rotations."""
    from jax.flatten_util import ravel_pytree

    from jaxtube._dynamics.integrator import _inertial_potential, _StepData
    from jaxtube._dynamics.step_system import (
        centroid_ties,
        constraints_and_energy,
        extended_state,
        inertial_hessian_blocks,
        step_factors,
    )
    from jaxtube._elements import dense_from_blocks
    from jaxtube._equilibrium import tube_reference_geometry

    structure, params = jt.cantilever(1.0, 0.075, 3e4, 3, jt.LinearLaw(300.0),
                                      jt.LinearLaw(200.0), mass_per_length=0.3)
    geometry = tube_reference_geometry(structure, params)
    rng = np.random.default_rng(3)

    def rand(*shape):
        return jnp.asarray(rng.standard_normal(shape))

    state = extended_state(structure, geometry, jt.initial_state(structure, params))
    z0, unravel = ravel_pytree(state)
    z = z0 + 0.4 * rand(z0.size)
    state = unravel(z)
    s, j = structure.segment_count, len(structure.spring_joint_topology().node)
    frame = jnp.linalg.qr(rand(s, 3, 3))[0]  # orthonormal
    data = _StepData(step=jnp.asarray(1e-3), centroid_predicted=rand(s, 3),
                     centroid_rate=rand(s, 3),
                     translational_mass=jnp.einsum("sij,skj->sik", frame, frame),
                     frame=frame, increment_predicted=0.1 * rand(s, 3),
                     angular_rate=rand(s, 3), inertia=jnp.abs(rand(s, 3)),
                     point_predicted=jnp.zeros((0, 3)), point_rate=jnp.zeros((0, 3)),
                     point_mass=jnp.zeros((0,)), joint_rotation=0.1 * rand(j, 3),
                     joint_rate=rand(j, 3), joint_damping=jnp.abs(rand(j, 3)),
                     mass_damping=jnp.asarray(3.0))
    lam = rand(3 * s)

    def dynamic_part(flat):
        moved = unravel(flat)
        return (_inertial_potential(structure, geometry, moved, data)
                + lam @ centroid_ties(structure, geometry, moved))

    def autodiff_and_assembled(st):
        flat = ravel_pytree(st)[0]
        jacobian = jax.jacfwd(
            lambda f: constraints_and_energy(structure, geometry, unravel(f), params)[1])(flat)
        return (jax.hessian(dynamic_part)(flat), jacobian,
                dense_from_blocks(st, inertial_hessian_blocks(structure, geometry, st, lam,
                                                              data)),
                step_factors(structure, geometry, params, st))

    expected, jacobian, assembled, factors = jax.jit(autodiff_and_assembled)(state)
    np.testing.assert_allclose(assembled, expected, rtol=0,
                               atol=1e-12 * float(jnp.max(jnp.abs(expected))))
    n, p = z.size, factors.aux_count
    tree, cons = np.zeros((p, n + p)), np.zeros((jacobian.shape[0], n + p))
    for matrix, blocks in ((tree, factors.tree), (cons, factors.constraint)):
        for rows, cols, values in blocks:
            np.add.at(matrix, (np.broadcast_to(rows, np.shape(values)),
                               np.broadcast_to(cols, np.shape(values))), np.asarray(values))
    factored = cons[:, :n] + cons[:, n:] @ np.linalg.solve(tree[:, n:], -tree[:, :n])
    np.testing.assert_allclose(factored, jacobian, rtol=0, atol=1e-12)
