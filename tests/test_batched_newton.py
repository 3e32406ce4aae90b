"""The batch-friendly Newton iteration (``NewtonKKT(globalisation="fixed_trials")``): under
``vmap`` each member's result equals its single solve, each member reports its own
convergence, and a member's iterates are those of the default backtracking iteration."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxtube as jt

FIXED = jt.NewtonKKT(globalisation="fixed_trials")


@pytest.fixture(scope="module")
def curves():
    """Displacement-controlled curves of a 10-segment tension-field cantilever through
    wrinkling and collapse (so the regularisation and the line search have work to do), at
    three pressures and a tip travel that one member cannot finish in 4 Newton steps."""
    law = jt.TensionFieldLaw(150e3, residual_stiffness_ratio=0.01)
    structure, params = jt.cantilever(1.0, 0.075, 2e4, 10, law, jt.LinearLaw(150.0))
    tip = structure.node_id("tube:end")

    def curve(pressure, travel, solver):
        p = eqx.tree_at(lambda q: q.pressure, params, jnp.full_like(params.pressure, pressure))
        path = jt.DisplacementControl(tip, [0, 0, -1], travel * jnp.linspace(0.1, 1.0, 10))
        sol = jt.solve_path(structure, p, path, solver)
        return sol.control_force, sol.state, sol.converged, sol.iterations, sol.result

    return curve


def test_vmap_members_equal_their_single_solves(curves):
    pressures = jnp.array([1.0e4, 2.0e4, 4.0e4])
    travels = jnp.array([0.3, 0.4, 0.25])
    batched = jax.jit(jax.vmap(lambda p, t: curves(p, t, FIXED)))(pressures, travels)
    single = jax.jit(lambda p, t: curves(p, t, FIXED))
    reference = jax.jit(lambda p, t: curves(p, t, jt.NewtonKKT()))
    for k in range(3):
        force, state, converged, iterations, result = single(pressures[k], travels[k])
        assert bool(np.all(converged)), f"member {k}"
        np.testing.assert_allclose(batched[0][k], force, rtol=1e-12, atol=1e-12)
        jax.tree.map(lambda b, s: np.testing.assert_allclose(b[k], s, rtol=1e-12, atol=1e-13),
                     batched[1], state)
        np.testing.assert_array_equal(batched[2][k], converged)
        np.testing.assert_array_equal(batched[3][k], iterations)
        # The same iterates as the backtracking iteration: the same Newton step counts and
        # the same converged curve.
        force_b, _, converged_b, iterations_b, _ = reference(pressures[k], travels[k])
        assert bool(np.all(converged_b))
        np.testing.assert_array_equal(iterations, iterations_b)
        np.testing.assert_allclose(force, force_b, rtol=1e-9)
    # Collapse was reached: the regularisation and line search were exercised on this path.
    assert int(np.max(batched[3])) >= 4


def test_vmap_reports_each_members_failure(curves):
    """A member given too few Newton steps fails alone, with code 1 and finite numbers."""
    solver = jt.NewtonKKT(globalisation="fixed_trials", max_steps=3)
    out = jax.jit(jax.vmap(lambda p, t: curves(p, t, solver)))(
        jnp.array([2.0e4, 2.0e4]), jnp.array([0.02, 0.6]))
    force, state, converged, iterations, result = (np.asarray(x) if not isinstance(x, dict)
                                                   else x for x in out)
    assert bool(converged[0].all())
    assert not bool(converged[1].all())
    assert set(np.unique(result[1][~converged[1]]).tolist()) <= {1, 2}
    assert np.all(np.isfinite(force))
    assert all(np.all(np.isfinite(np.asarray(v))) for v in state.values())


def test_settings_are_checked():
    with pytest.raises(ValueError, match="globalisation"):
        jt.NewtonKKT(globalisation="trust_region")
    with pytest.raises(ValueError, match="line_search_trials"):
        jt.NewtonKKT(globalisation="fixed_trials", line_search_trials=0)
