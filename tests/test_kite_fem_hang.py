"""A small kite written in kite_fem's format, imported and hung: balance of forces and
moments with the suspension reactions, line states reported, numbering kept, and gradients
of hung node positions with respect to a line's rest length and the tube pressure against
central finite differences (float64). One structure, two compiled programs."""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxtube as jt
from jaxtube._io.kite_fem_run import weight_and_reactions

from .kite_fem_mini import SUSPENSION, mini_kite_arrays, write_mini_kite

CENTRE_LOAD_KG, TIP_LOAD_KG = 0.2, 0.05


@pytest.fixture(scope="module")
def mini(tmp_path_factory):
    path = tmp_path_factory.mktemp("mini") / "mini.npz"
    write_mini_kite(path)
    imported = jt.import_kite_fem(path, suspension=SUSPENSION, centre_node=3,
                                  centre_load_kg=CENTRE_LOAD_KG, tip_nodes=(7, 9),
                                  tip_load_kg=TIP_LOAD_KG)
    hang = jax.jit(functools.partial(jt.hang_kite, imported.structure, steps=2))
    return imported, hang


def test_mini_kite_hangs_in_balance(mini):
    imported, hang = mini
    solution = hang(imported.params)
    jt.check_converged(solution, "mini kite")
    arrays = mini_kite_arrays()
    reference = arrays["initial_conditions_array"][:, :3]
    positions = imported.kite_positions(np.asarray(solution.node_position))
    assert positions.shape == (2, 13, 3)
    # Held node 0 and the suspension stay; the kite moves (it sags under gravity).
    np.testing.assert_array_equal(positions[:, 0], np.broadcast_to(reference[0], (2, 3)))
    np.testing.assert_allclose(positions[-1, [11, 12]], reference[[11, 12]], atol=1e-10)
    assert np.linalg.norm(positions[-1, 1:11] - reference[1:11], axis=1).max() > 1e-3
    # Every step: reactions balance weight plus loads, forces and moments.
    mass = arrays["initial_conditions_array"][:, 6].sum() + CENTRE_LOAD_KG
    for step in range(2):
        balance = weight_and_reactions(imported, solution, step)
        factor = (step + 1) / 2
        np.testing.assert_allclose(balance["weight_and_loads_N"],
                                   [0.0, 0.0, factor * 9.81 * mass], atol=1e-10)
        np.testing.assert_allclose(balance["reaction_sum_N"], -balance["weight_and_loads_N"],
                                   atol=1e-7 * 9.81 * mass)
        np.testing.assert_allclose(balance["reaction_moment_Nm"], -balance["applied_moment_Nm"],
                                   atol=1e-7 * 9.81 * mass)
    # Line states: every line and the rope reported; the suspension lines carry the kite.
    taut = np.asarray(solution.line_taut)[-1]
    tension = np.asarray(solution.line_tension)[-1]
    assert taut.shape == (11,) and np.asarray(solution.pulley_taut).shape == (2, 1)
    assert np.all(taut[5:]) and np.all(tension[5:] > 0.1)
    assert np.all(tension[~taut] == 0.0)
    # The lines' tensions are k (l - L0) where taut beyond the smoothing band.
    model = imported.model
    length = np.asarray(solution.line_length)[-1]
    strain = (length - model.spring_rest_length) / model.spring_rest_length
    clear = strain > 1e-3
    np.testing.assert_allclose(tension[clear], (model.spring_stiffness
                                                * (length - model.spring_rest_length))[clear],
                               rtol=1e-12)


def test_mini_kite_gradients(mini):
    imported, _ = mini
    structure = imported.structure
    watched = imported.node_index[[7, 9, 10, 3]]

    def hung_positions(rest_length, pressure):
        params = eqx.tree_at(
            lambda p: (p.elements.line_rest_length, p.pressure), imported.params,
            (imported.params.elements.line_rest_length.at[9].set(rest_length),
             jnp.full_like(imported.params.pressure, pressure)))
        solution = jt.hang_kite(structure, params, steps=1)
        return solution.node_position[-1, watched].ravel(), solution.converged[-1]

    rest0 = float(imported.params.elements.line_rest_length[9])
    pressure0 = 0.2e5
    solve = jax.jit(hung_positions)
    x0, ok = solve(rest0, pressure0)
    assert bool(ok)
    tangent = jax.jit(lambda r, p, dr, dp: jax.jvp(
        lambda rr, pp: hung_positions(rr, pp)[0], (r, p), (dr, dp))[1])
    d_rest = tangent(rest0, pressure0, 1.0, 0.0)
    d_pressure = tangent(rest0, pressure0, 0.0, 1.0)
    for step, derivative, h in ((lambda h: (rest0 + h, pressure0), d_rest, 1e-6),
                                (lambda h: (rest0, pressure0 + h), d_pressure, 1.0)):
        plus, ok_plus = solve(*step(h))
        minus, ok_minus = solve(*step(-h))
        assert bool(ok_plus) and bool(ok_minus)
        central = (np.asarray(plus) - np.asarray(minus)) / (2 * h)
        scale = np.abs(central).max()
        assert scale > 0  # the watched nodes do move
        np.testing.assert_allclose(np.asarray(derivative), central, atol=1e-5 * scale)
