"""A small kite written in kite_fem's format, imported and hung: balance of forces and
moments with the suspension reactions at every gravity step, line states reported, node
numbering kept, and gradients of hung node positions with respect to a bridle line's rest
length and the tube pressure against central finite differences (float64).

One compiled program serves every check: the hang (two gravity steps) under ``jax.jvp``,
which returns the solution and its tangent; finite differences reuse it at shifted inputs.
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxtube as jt
from jaxtube import deformed_shape_figure, weight_and_reactions
from jaxtube import kite_fem_line_table as line_table
from jaxtube import kite_fem_reference_positions as reference_positions

from .kite_fem_mini import SUSPENSION, mini_kite_arrays, write_mini_kite

CENTRE_LOAD_KG, TIP_LOAD_KG = 0.2, 0.05
BRIDLE_LINE = 9  # spring row 9: suspension node 11 to the pulley's bridle node 10
PRESSURE_PA = 0.2e5


@pytest.fixture(scope="module")
def mini(tmp_path_factory):
    path = tmp_path_factory.mktemp("mini") / "mini.npz"
    write_mini_kite(path)
    imported = jt.import_kite_fem(path, suspension=SUSPENSION, centre_node=3,
                                  centre_load_kg=CENTRE_LOAD_KG, tip_nodes=(7, 9),
                                  tip_load_kg=TIP_LOAD_KG)

    def hang(rest_length, pressure):
        params = eqx.tree_at(
            lambda p: (p.elements.line_rest_length, p.pressure), imported.params,
            (imported.params.elements.line_rest_length.at[BRIDLE_LINE].set(rest_length),
             jnp.full_like(imported.params.pressure, pressure)))
        return jt.hang_kite(imported.structure, params, steps=2)

    @jax.jit
    def hang_and_tangent(rest_length, pressure, d_rest_length, d_pressure):
        return jax.jvp(hang, (rest_length, pressure), (d_rest_length, d_pressure))

    rest0 = float(imported.params.elements.line_rest_length[BRIDLE_LINE])
    return imported, functools.partial(hang_and_tangent), rest0


def test_mini_kite_hangs_in_balance(mini):
    imported, hang_and_tangent, rest0 = mini
    solution, _ = hang_and_tangent(rest0, PRESSURE_PA, 0.0, 0.0)
    jt.check_converged(solution, "mini kite")
    arrays = mini_kite_arrays()
    reference = arrays["initial_conditions_array"][:, :3]
    positions = imported.kite_positions(np.asarray(solution.node_position))
    assert positions.shape == (2, 13, 3)
    # Held node 0 and the suspension stay; the kite moves (it sags under gravity).
    np.testing.assert_array_equal(positions[:, 0], np.broadcast_to(reference[0], (2, 3)))
    np.testing.assert_allclose(positions[-1, [11, 12]], reference[[11, 12]], atol=1e-10)
    assert np.linalg.norm(positions[-1, 1:11] - reference[1:11], axis=1).max() > 1e-3
    # Every step: the reactions balance weight plus loads, forces and moments.
    mass = arrays["initial_conditions_array"][:, 6].sum() + CENTRE_LOAD_KG
    for step in range(2):
        balance = weight_and_reactions(imported, solution, step)
        np.testing.assert_allclose(balance["weight_and_loads_N"],
                                   [0.0, 0.0, (step + 1) / 2 * 9.81 * mass], atol=1e-10)
        np.testing.assert_allclose(balance["reaction_sum_N"], -balance["weight_and_loads_N"],
                                   atol=1e-7 * 9.81 * mass)
        np.testing.assert_allclose(balance["reaction_moment_Nm"], -balance["applied_moment_Nm"],
                                   atol=1e-7 * 9.81 * mass)
    # Every line and the rope reported; the bridle lines carry the kite.
    rows = line_table(imported, solution)
    assert len(rows) == 11 + 1 and {r["state"] for r in rows} <= {"taut", "slack"}
    assert [r["element"] for r in rows] == ["canopy"] * 5 + ["bridle"] * 6 + ["pulley"]
    taut = np.asarray(solution.line_taut)[-1]
    tension = np.asarray(solution.line_tension)[-1]
    assert np.all(taut[5:]) and np.all(tension[5:] > 0.1)
    assert np.all(tension[~taut] == 0.0)
    # Tension k (l - L0) where a line is taut beyond the smoothing band (exact there).
    model = imported.model
    length = np.asarray(solution.line_length)[-1]
    stretch = length - model.spring_rest_length
    half_band = 0.5 * float(imported.params.elements.tension_smoothing)
    clear = stretch / model.spring_rest_length >= half_band
    assert clear.sum() >= 4
    np.testing.assert_allclose(tension[clear], (model.spring_stiffness * stretch)[clear],
                               rtol=1e-12)
    # The shape figure draws the lines (taut and slack apart), the rope, masses, fixed points.
    figure = deformed_shape_figure(
        imported.structure, reference_positions(imported), np.asarray(solution.node_position),
        np.asarray(solution.converged), line_taut=np.asarray(solution.line_taut),
        pulley_taut=np.asarray(solution.pulley_taut),
        point_mass=np.asarray(imported.params.elements.point_mass),
        gravity=np.asarray(imported.params.gravity))
    labels = [t.get_text() for t in figure.axes[0].get_legend().get_texts()]
    expected = {f"line, taut ({int(taut[5:].sum())})", "rope over pulley, taut (1)", "pulley",
                "fixed point", "point masses (10, 1 kg)"}
    if np.any(taut[:5]):
        expected.add(f"canopy, taut ({int(taut[:5].sum())})")
    if not np.all(taut[:5]):
        expected.add(f"canopy, slack ({int((~taut[:5]).sum())})")
    assert expected <= set(labels), labels
    assert figure.axes[0].zaxis_inverted()  # gravity (+z) down the page


def test_mini_kite_gradients(mini):
    """d(hung positions)/d(bridle rest length) and d/d(tube pressure): forward mode through
    the implicit function theorem against central differences."""
    imported, hang_and_tangent, rest0 = mini
    watched = imported.node_index[[7, 9, 10, 3]]  # strut ends, bridle node, crown

    def final(solution):
        return np.asarray(solution.node_position)[-1, watched].ravel()

    for tangent, h in (((1.0, 0.0), 1e-6), ((0.0, 1.0), 1.0)):
        solution, derivative = hang_and_tangent(rest0, PRESSURE_PA, *tangent)
        plus, _ = hang_and_tangent(rest0 + h * tangent[0], PRESSURE_PA + h * tangent[1],
                                   0.0, 0.0)
        minus, _ = hang_and_tangent(rest0 - h * tangent[0], PRESSURE_PA - h * tangent[1],
                                    0.0, 0.0)
        for s in (solution, plus, minus):
            jt.check_converged(s, "mini kite")
        central = (final(plus) - final(minus)) / (2 * h)
        scale = np.abs(central).max()
        assert scale > 0  # the watched nodes do move
        np.testing.assert_allclose(final(derivative), central, atol=1e-5 * scale)


def test_hang_schedule_needs_one_width_per_stage(mini):
    imported, _, _ = mini
    with pytest.raises(ValueError, match="expected 2 widths"):
        jt.hang_kite(imported.structure, imported.params, load_factors=[0.5, 1.0],
                     tension_smoothing=[1e-2, 1e-3, 1e-4])
