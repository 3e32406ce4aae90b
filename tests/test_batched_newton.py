"""The Newton iteration under ``vmap``: each member's result equals its single solve (the
same iterates), and each member reports its own convergence."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxtube as jt

STEPS = 10


@pytest.fixture(scope="module")
def curves():
    """``(pressure [Pa], travel [m], solver) -> curve``: displacement-controlled curves of an
    8-segment tension-field cantilever, 1 m long, through wrinkling and collapse (so the
    regularisation and the line search have work to do), in ``STEPS`` equal steps."""
    law = jt.TensionFieldLaw(150e3, residual_stiffness_ratio=0.01)
    structure, params = jt.cantilever(1.0, 0.075, 2e4, 8, law, jt.LinearLaw(150.0))
    tip = structure.node_id("tube:end")

    def curve(pressure, travel, solver):
        p = eqx.tree_at(lambda q: q.pressure, params, jnp.full_like(params.pressure, pressure))
        path = jt.DisplacementControl(tip, [0, 0, -1], travel * jnp.linspace(0.1, 1.0, STEPS))
        sol = jt.solve_path(structure, p, path, solver)
        return sol.control_force, sol.state, sol.converged, sol.iterations, sol.result

    return curve


@pytest.mark.slow
def test_vmap_members_equal_their_single_solves(curves):
    """Three members through collapse and one asked for a tip travel longer than the tube
    (no equilibrium exists): the batch reports each member's own outcome, and every member
    follows its single solve: the same converged steps, the same Newton step counts (the same
    iterates) and the same curve."""
    pressures = jnp.array([1.0e4, 2.0e4, 4.0e4, 2.0e4])
    travels = jnp.array([0.3, 0.4, 0.25, 1.5])  # m; the tube is 1 m long
    batched = jax.jit(jax.vmap(lambda p, t: curves(p, t, jt.NewtonKKT())))(pressures, travels)
    single = jax.jit(lambda p, t: curves(p, t, jt.NewtonKKT()))
    for k in range(4):
        force, state, converged, iterations, result = single(pressures[k], travels[k])
        converged = np.asarray(converged)
        np.testing.assert_array_equal(batched[2][k], converged)
        # On converged steps: the same Newton step counts and the same solution. (A failed
        # step's numbers are not an answer: two programs round differently and diverge.)
        np.testing.assert_array_equal(np.asarray(batched[3][k])[converged],
                                      np.asarray(iterations)[converged])
        np.testing.assert_allclose(np.asarray(batched[0][k])[converged],
                                   np.asarray(force)[converged], rtol=1e-10, atol=1e-12)
        jax.tree.map(lambda b, s: np.testing.assert_allclose(
            np.asarray(b[k])[converged], np.asarray(s)[converged], rtol=1e-10, atol=1e-12),
            batched[1], state)
        if k < 3:
            assert bool(np.all(converged)), f"member {k}"
            np.testing.assert_array_equal(batched[4][k], result)
    # The impossible member: the steps beyond 1 m fail, say so with a failure code, and its
    # numbers stay finite; its first step converges.
    travel = np.asarray(travels[3] * jnp.linspace(0.1, 1.0, STEPS))
    converged = np.asarray(batched[2][3])
    assert bool(converged[0]) and not bool(converged[travel > 1.0].any())
    assert set(np.asarray(batched[4][3])[travel > 1.0].tolist()) <= {1, 2}
    assert np.all(np.isfinite(np.asarray(batched[0][3])))
    assert all(np.all(np.isfinite(np.asarray(v[3]))) for v in batched[1].values())
    # Collapse was reached: the regularisation and line search were exercised on this path.
    assert int(np.max(batched[3][:3])) >= 4

