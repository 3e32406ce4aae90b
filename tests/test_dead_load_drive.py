"""``jaxtube.drive_to_dead_load``: a dead load reached through displacement control of its
node is the dead-load equilibrium. Checked against a closed form across a slack-taut change
(point node on two lines), the planar statics of a cantilever on the tension-field law's
collapse plateau, an independent force-control path, and finite differences of the
gradient (float64)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxtube as jt

from .helpers import central_difference

K, L0 = 100.0, 0.9  # the two lines of the point-node case: N/m, m


def test_point_node_driven_across_a_slack_taut_change_matches_the_closed_form():
    """A point between fixed points 1 m above and below it on two lines of rest length
    0.9 m, with 40 N upwards: past 2 k (1 - L0) = 20 N the upper line is slack, and the
    closed form is ``z = F / k - (1 - L0) = 0.3 m`` with the lower line carrying 40 N."""
    force = 40.0
    points = [jt.FixedPoint("top", (0.0, 0.0, 1.0)), jt.FixedPoint("bottom", (0.0, 0.0, -1.0)),
              jt.PointNode("P", (0.0, 0.0, 0.0), force=(0.0, 0.0, force))]
    lines = [jt.Line("top", "P", K, L0), jt.Line("P", "bottom", K, L0)]
    structure, params = jt.build_structure([], [], points=points, lines=lines, gravity=(0, 0, 0))
    node = structure.node_id("P")
    np.testing.assert_allclose(jt.node_dead_load(structure, params, node), [0, 0, force])
    driven = jax.jit(lambda p: jt.drive_to_dead_load(structure, p, node, (0, 0, 1), steps=12,
                                                     max_increment=0.1))(params)
    assert bool(driven.reached) and bool(driven.equilibrium.converged)
    np.testing.assert_allclose(float(driven.target_force), force)
    z = float(driven.equilibrium.node_position[node, 2])
    np.testing.assert_allclose(z, force / K - (1.0 - L0), atol=1e-11)
    tension = np.asarray(driven.equilibrium.line_tension)
    assert tension[0] == 0.0  # the upper line is slack: exactly nothing
    np.testing.assert_allclose(tension[1], force, rtol=1e-10)
    # The start: the point held at its undeformed position, where the stretched lines
    # balance; the actuator carries nothing.
    assert bool(driven.start.converged)
    assert float(driven.start.control_displacement) == 0.0
    assert abs(float(driven.start.control_force)) <= 1e-12
    # The path: every accepted step converged, and it crossed the slack-taut change; the
    # drive stopped once it carried the load, the steps after it not solved.
    taken = int(driven.steps_taken)
    assert 0 < taken < 12
    accepted = np.asarray(driven.path.converged)
    assert not accepted[taken:].any()
    path_force = np.asarray(driven.path.control_force)[accepted]
    assert path_force.min() < 2 * K * (1 - L0) < path_force.max()
    assert abs(path_force[-1] - force) <= 1e-6 * force


@pytest.fixture(scope="module")
def plateau_cantilever():
    """Breukels-type tension-field cantilever (1 m, r = 75 mm, 0.2 bar, 10 segments) whose
    collapse moment ``M_c = pi p r^3`` makes a tip load near ``M_c / L`` sit on the soft
    plateau; ``solve(params)``: the driven tip load (jitted once)."""
    law = jt.TensionFieldLaw(150e3, residual_stiffness_ratio=0.01)
    structure, params = jt.cantilever(1.0, 0.075, 2e4, 10, law, jt.LinearLaw(150.0))
    tip = structure.node_id("tube:end")
    collapse_force = np.pi * 2e4 * 0.075**3 / 1.0

    def drive(p):
        return jt.drive_to_dead_load(structure, p, tip, (0, 0, -1), steps=24,
                                     max_increment=0.05)

    def with_tip_load(weight):
        return jt.with_node_dead_load(structure, params, tip, jnp.stack(
            [jnp.zeros(()), jnp.zeros(()), -jnp.asarray(weight, float)]))

    return structure, tip, collapse_force, jax.jit(drive), with_tip_load


@pytest.mark.parametrize("fraction", [0.98, 1.3])
def test_driven_cantilever_on_the_collapse_plateau_satisfies_planar_statics(
        plateau_cantilever, fraction):
    """At 0.98 and 1.3 ``M_c / L`` (the soft plateau and beyond): the driven equilibrium's
    joint moments are ``W a_k`` (``a_k`` the lever arm from joint ``k`` to the tip) to 1e-10
    of the root moment, and it equals an independent force-control path of 20 load steps."""
    structure, tip, collapse_force, drive, with_tip_load = plateau_cantilever
    weight = fraction * collapse_force
    params = with_tip_load(weight)
    driven = drive(params)
    assert bool(driven.reached) and bool(driven.equilibrium.converged)
    x = np.asarray(driven.equilibrium.node_position)
    arm = x[tip, 0] - x[:tip, 0]   # joints sit at nodes 0..S-1, the load along -z
    moment = np.linalg.norm(np.asarray(driven.equilibrium.joint_moment_world), axis=1)
    np.testing.assert_allclose(moment, weight * arm, rtol=0, atol=1e-10 * weight * arm[0])
    assert int(np.max(driven.equilibrium.joint_regime)) >= 1  # past the wrinkling onset
    stepped = jax.jit(lambda p: jt.solve_path(structure, p, jt.ForceControl(
        jnp.linspace(0.05, 1.0, 20))))(params)
    jt.check_converged(stepped, "force-control path")
    np.testing.assert_allclose(x, np.asarray(stepped.node_position[-1]), atol=1e-9)


def test_driven_equilibrium_gradient_matches_finite_differences(plateau_cantilever):
    """d(tip deflection)/d(W) through the drive (implicit function theorem at the dead-load
    equilibrium) against central differences of the driven solve, float64."""
    structure, tip, collapse_force, drive, with_tip_load = plateau_cantilever

    def tip_z(weight):
        return drive(with_tip_load(weight)).equilibrium.node_position[tip, 2]

    weight = 0.9 * collapse_force
    derivative = float(jax.jit(jax.grad(tip_z))(weight))
    reference = central_difference(lambda w: float(tip_z(w)), weight, rel_step=1e-6)
    assert derivative < 0.0
    np.testing.assert_allclose(derivative, reference, rtol=1e-6)
