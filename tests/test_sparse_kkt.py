"""The sparse KKT route (KLU on the pattern of the Hessian blocks) against the dense route:
the same solutions and the same gradients through the implicit function theorem (1e-9
relative), on a chain (torque, line load, self-weight, shear, displacement control), an
arch clamped at both ends with a strut, a closed ring and a frame with a pinned connection
(the structures of ``tests/test_solver.py``'s Hessian test). Also: the sparse pattern's
matrix equals the dense one, and importing klujax leaves JAX's platform setting alone."""

import os
import subprocess
import sys
import textwrap

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxtube as jt

from .test_solver import _hessian_cases

CASES = _hessian_cases()


def _solve_and_gradient(structure, params, control, route):
    """Node positions at equilibrium and the gradient of a scalar of them w.r.t. the
    pressure and the node forces (through the implicit function theorem)."""
    solver = jt.NewtonKKT(linear_solver=route)
    path = None
    if control is not None:
        path = jt.DisplacementControl(control[0], control[1], jnp.array([control[2]]))
    weights = jnp.asarray(np.random.default_rng(1).standard_normal(
        params.node_position.shape))

    def measure(pressure, node_force):
        p = eqx.tree_at(lambda q: (q.pressure, q.node_force), params, (pressure, node_force))
        sol = jt.equilibrium(structure, p, path, solver=solver)
        return jnp.sum(weights * sol.node_position), sol

    (value, sol), grads = jax.value_and_grad(measure, argnums=(0, 1), has_aux=True)(
        params.pressure, params.node_force)
    return sol.node_position, sol.converged, sol.multipliers, grads


@pytest.mark.parametrize("case", range(len(CASES)), ids=[c[0] for c in CASES])
def test_sparse_and_dense_routes_agree(case):
    _, (structure, params), control = CASES[case]
    results = {route: jax.jit(lambda p, route=route: _solve_and_gradient(
        structure, p, control, route))(params) for route in ("dense", "sparse")}
    (pos_d, ok_d, lam_d, grad_d), (pos_s, ok_s, lam_s, grad_s) = results.values()
    assert bool(ok_d) and bool(ok_s)
    scale = float(jnp.max(jnp.abs(pos_d)))
    np.testing.assert_allclose(pos_s, pos_d, rtol=1e-9, atol=1e-9 * scale)
    np.testing.assert_allclose(lam_s, lam_d, rtol=1e-9,
                               atol=1e-9 * float(jnp.max(jnp.abs(lam_d))))
    assert float(jnp.max(jnp.abs(grad_d[1]))) > 0.0  # the force gradient is never zero
    for g_s, g_d in zip(grad_s, grad_d):  # (the pressure's is, for a linear law)
        np.testing.assert_allclose(g_s, g_d, rtol=1e-9,
                                   atol=1e-9 * float(jnp.max(jnp.abs(g_d))) + 1e-300)


def test_sparse_pattern_matrix_equals_dense_matrix():
    """The KKT values scattered on the sparse pattern are the dense KKT matrix (with
    regularisation terms), for the arch with a strut at a random state."""
    from jax.flatten_util import ravel_pytree

    from jaxtube._mechanics import energy_terms_and_constraints as _objective_terms
    from jaxtube._mechanics import lagrangian_hessian_blocks, reference_geometry
    from jaxtube._solver.kkt_linear import DenseKKT, SparseKKT

    _, (structure, params), _ = CASES[1]
    geometry = reference_geometry(structure, params)
    state0 = jt.initial_state(structure, params)
    z0, unravel = ravel_pytree(state0)
    rng = np.random.default_rng(3)
    z = z0 + 0.2 * jnp.asarray(rng.standard_normal(z0.shape))
    jacobian = jax.jacrev(lambda zz: _objective_terms(structure, geometry, unravel(zz), params,
                                                      None)[1])(z)
    m, n = jacobian.shape
    lam = jnp.asarray(rng.standard_normal(m))
    blocks = lagrangian_hessian_blocks(structure, geometry, params, None, unravel(z), lam)
    dense, sparse = DenseKKT(n, m), SparseKKT(blocks, n, m)
    matrix = dense.kkt(dense.hessian(blocks), jacobian, 0.3, 0.01)
    values = sparse.kkt(sparse.hessian(blocks), jacobian, 0.3, 0.01)
    rebuilt = np.zeros((n + m, n + m))
    np.add.at(rebuilt, (sparse.Ai, sparse.Aj), np.asarray(values))
    np.testing.assert_allclose(rebuilt, matrix, rtol=1e-14, atol=1e-14 * float(
        jnp.max(jnp.abs(matrix))))
    assert sparse.nnz < 0.5 * (n + m) ** 2
    vector = jnp.asarray(rng.standard_normal(n))
    np.testing.assert_allclose(sparse.hessian_times(sparse.hessian(blocks), vector),
                               dense.hessian(blocks) @ vector, rtol=1e-12, atol=1e-12)
    rhs = jnp.asarray(rng.standard_normal(n + m))
    np.testing.assert_allclose(sparse.solve(values, rhs), jnp.linalg.solve(matrix, rhs),
                               rtol=1e-9, atol=1e-12)


def test_importing_klujax_restores_the_platform_setting():
    """klujax 0.5 sets ``jax_platform_name = "cpu"`` (and x64) for the whole process at
    import; jaxtube imports it lazily and restores both. Fresh process: klujax not yet
    imported, a non-default platform setting must survive."""
    script = textwrap.dedent("""
        import sys
        import jax
        import jaxtube
        from jaxtube._solver.kkt_linear import klujax_module
        assert "klujax" not in sys.modules, "klujax imported eagerly"
        jax.config.update("jax_platform_name", "")
        jax.config.update("jax_enable_x64", False)
        klujax_module()
        assert "klujax" in sys.modules
        print("AFTER", repr(jax.config.values["jax_platform_name"]),
              jax.config.values["jax_enable_x64"])
    """)
    environment = dict(os.environ)
    done = subprocess.run([sys.executable, "-c", script], env=environment, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "AFTER '' False" in done.stdout
