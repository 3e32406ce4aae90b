"""The sparse KKT routes (KLU on the pattern of the Hessian blocks, and the augmented route)
against the dense route: the same solutions (1e-9 relative) on a chain (torque, line load,
self-weight, shear, displacement control) and an arch clamped at both ends with a strut, and
on the chain the same gradients through the implicit function theorem (the two structures
of ``tests/test_solver.py``'s Hessian test: a closed ring's closure and a pinned connection
use the same code paths as the arch's second clamp and the chain's support, and every
structure's constraint pattern and factors are checked below). Also: the sparse pattern's
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


def _solve_and_gradient(structure, params, control, route, gradient):
    """Node positions at equilibrium and (``gradient``) the gradient of a scalar of them
    w.r.t. the pressure and the node forces (through the implicit function theorem)."""
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

    if not gradient:
        sol = measure(params.pressure, params.node_force)[1]
        return sol.node_position, sol.converged, sol.multipliers, ()
    (value, sol), grads = jax.value_and_grad(measure, argnums=(0, 1), has_aux=True)(
        params.pressure, params.node_force)
    return sol.node_position, sol.converged, sol.multipliers, grads


# Each case compiles a solve for each of the three routes. The gradient's linear solve is the
# transposed (symmetric) KKT system of the Newton step's, on the same route: the chain
# (displacement control, every load kind) compares gradients too, the arch (two clamps, a
# strut's connection) the solutions, each compilation of a gradient costing about twice a
# solve's.
@pytest.mark.parametrize("case, gradient", [(0, True), (1, False)],
                         ids=[c[0] for c in CASES[:2]])
def test_sparse_and_dense_routes_agree(case, gradient):
    _, (structure, params), control = CASES[case]
    routes = ("dense", "sparse", "augmented")
    results = {route: jax.jit(lambda p, route=route: _solve_and_gradient(
        structure, p, control, route, gradient))(params) for route in routes}
    pos_d, ok_d, lam_d, grad_d = results["dense"]
    assert bool(ok_d)
    if gradient:
        assert float(jnp.max(jnp.abs(grad_d[1]))) > 0.0  # the force gradient is never zero
    scale = float(jnp.max(jnp.abs(pos_d)))
    for route in routes[1:]:
        pos_s, ok_s, lam_s, grad_s = results[route]
        assert bool(ok_s), route
        np.testing.assert_allclose(pos_s, pos_d, rtol=1e-9, atol=1e-9 * scale, err_msg=route)
        np.testing.assert_allclose(lam_s, lam_d, rtol=1e-9, err_msg=route,
                                   atol=1e-9 * float(jnp.max(jnp.abs(lam_d))))
        for g_s, g_d in zip(grad_s, grad_d, strict=True):  # (pressure's: zero, linear law)
            np.testing.assert_allclose(g_s, g_d, rtol=1e-9, err_msg=route,
                                       atol=1e-9 * float(jnp.max(jnp.abs(g_d))) + 1e-300)


def test_sparse_pattern_matrix_equals_dense_matrix():
    """The KKT values scattered on the sparse pattern are the dense KKT matrix (with
    regularisation terms), for the arch with a strut at a random state."""
    from jax.flatten_util import ravel_pytree

    from jaxtube._equilibrium import _hessian as model_hessian  # jitted: one compilation
    from jaxtube._mechanics import energy_terms_and_constraints as _objective_terms
    from jaxtube._mechanics import reference_geometry
    from jaxtube._solver.kkt_linear import DenseKKT, SparseKKT

    _, (structure, params), _ = CASES[1]
    geometry = reference_geometry(structure, params)
    state0 = jt.initial_state(structure, params)
    z0, unravel = ravel_pytree(state0)
    rng = np.random.default_rng(3)
    z = z0 + 0.2 * jnp.asarray(rng.standard_normal(z0.shape))
    jacobian = jax.jit(jax.jacrev(lambda zz: _objective_terms(
        structure, geometry, unravel(zz), params, None)[1]))(z)
    m, n = jacobian.shape
    lam = jnp.asarray(rng.standard_normal(m))
    blocks = model_hessian(unravel(z), lam, (params, geometry, None), structure=structure,
                           control_node=None)
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


def _pattern_structures(tmp_path):
    """Every case above (the chain with its displacement control), the mini kite in kite_fem's
    format (attachment ties, fixed points, a pulley; once more with a displacement control on
    a free point node) and the V3 kite (ties on long paths)."""
    from .kite_fem_mini import SUSPENSION, write_mini_kite

    cases = [(name, structure, params, None if control is None else control[0])
             for name, (structure, params), control in CASES]
    write_mini_kite(tmp_path / "mini.npz")
    mini = jt.import_kite_fem(tmp_path / "mini.npz", suspension=SUSPENSION, centre_node=3,
                              tip_nodes=(7, 9), pressure_bar=0.2)
    cases.append(("mini kite", mini.structure, mini.params, None))
    bridle_point = int(mini.node_index[10])  # a free point node: the control's row there
    assert bridle_point >= mini.structure.node_count
    cases.append(("mini kite, point-node control", mini.structure, mini.params, bridle_point))
    v3 = jt.import_kite_fem(os.path.join(os.path.dirname(__file__), os.pardir, "experiments",
                                         "data", "v3_hanging", "kite_fem", "initial.npz"),
                            pressure_bar=0.15)
    cases.append(("V3 kite", v3.structure, v3.params, None))
    return cases


def test_constraint_pattern_covers_the_jacobian(tmp_path):
    """The static constraint-Jacobian pattern given to the sparse route
    (``jaxtube._mechanics.constraint_pattern``) holds every entry that is nonzero at random
    states (three per structure, large rotations), and no row is empty; on the V3 kite it is
    far sparser than dense (what makes its KKT pattern sparse)."""
    from jax.flatten_util import ravel_pytree

    from jaxtube._equilibrium import tube_reference_geometry
    from jaxtube._mechanics import energy_terms_and_constraints as _objective_terms
    from jaxtube._mechanics.constraint_pattern import constraint_jacobian_pattern

    rng = np.random.default_rng(5)
    for name, structure, params, control_node in _pattern_structures(tmp_path):
        geometry = tube_reference_geometry(structure, params)
        state0 = jt.initial_state(structure, params)
        z0, unravel = ravel_pytree(state0)
        control = None if control_node is None else (control_node, jnp.array([0.0, 0.0, 1.0]),
                                                     jnp.asarray(0.01))
        rows, cols = constraint_jacobian_pattern(structure, state0, control_node)
        jac_fn = jax.jit(jax.jacfwd(lambda zz: _objective_terms(
            structure, geometry, unravel(zz), params, control)[1]))
        m, n = jax.eval_shape(jac_fn, z0).shape
        allowed = np.zeros((m, n), bool)
        allowed[rows, cols] = True
        assert allowed.any(axis=1).all(), name
        for _ in range(3):
            z = z0 + 0.5 * jnp.asarray(rng.standard_normal(z0.shape))
            nonzero = np.asarray(jac_fn(z)) != 0.0
            missed = np.argwhere(nonzero & ~allowed)
            assert missed.size == 0, f"{name}: nonzero Jacobian entries outside the pattern " \
                                     f"(row, column): {missed[:5].tolist()}"
        if name == "V3 kite":
            assert rows.size < 0.1 * m * n, rows.size


def test_constraint_factors_equal_the_jacobian(tmp_path):
    """The factored constraint Jacobian of the augmented route
    (``jaxtube._mechanics.constraint_factors``: ``J = C_z + C_w G^{-1} F``) equals the
    autodiff Jacobian of the constraints at random states with large rotations, on every
    structure of the pattern test (supports, loop closures, ties on long paths, controls on
    tube and point nodes); and on the V3 kite the augmented KKT matrix's LU factors are far
    smaller than the plain sparse route's (the reason for the route)."""
    from jax.flatten_util import ravel_pytree

    from jaxtube._equilibrium import _factors as model_factors  # jitted: one compilation
    from jaxtube._equilibrium import tube_reference_geometry
    from jaxtube._mechanics import energy_terms_and_constraints as _objective_terms

    rng = np.random.default_rng(7)
    for name, structure, params, control_node in _pattern_structures(tmp_path):
        geometry = tube_reference_geometry(structure, params)
        state0 = jt.initial_state(structure, params)
        z0, unravel = ravel_pytree(state0)
        n = z0.size
        control = None if control_node is None else (
            control_node, jnp.array([0.3, -0.2, 0.9]), jnp.asarray(0.01))
        c_args = None if control is None else control[1:]
        jac_fn = jax.jit(jax.jacfwd(lambda zz: _objective_terms(
            structure, geometry, unravel(zz), params, control)[1]))
        for _ in range(2):
            z = z0 + 0.5 * jnp.asarray(rng.standard_normal(z0.shape))
            factors = model_factors(unravel(z), (params, geometry, c_args),
                                    structure=structure, control_node=control_node)
            p = factors.aux_count
            tree = np.zeros((p, n + p))
            for rows, cols, values in factors.tree:
                np.add.at(tree, (np.broadcast_to(rows, np.shape(values)),
                                 np.broadcast_to(cols, np.shape(values))), np.asarray(values))
            cons = np.zeros((jac_fn(z).shape[0], n + p))
            for rows, cols, values in factors.constraint:
                np.add.at(cons, (rows, cols), np.asarray(values))
            minus_f, g = tree[:, :n], tree[:, n:]
            factored = cons[:, :n] + cons[:, n:] @ np.linalg.solve(g, -minus_f)
            expected = np.asarray(jac_fn(z))
            np.testing.assert_allclose(factored, expected, rtol=0, atol=1e-12, err_msg=name)
