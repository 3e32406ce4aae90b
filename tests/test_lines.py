"""Point nodes, tension-only lines, pulleys and masses against closed forms and independent
solves (issue 14).

- the smoothed tension-only law: exact outside the blend, error at most ``k L0 delta / 8``
  inside, C1, its energy integrates the tension;
- a hanging chain of point masses on elastic links against the discrete catenary (an
  independent scipy solve of the chain's force balance), two link counts;
- a point between two lines through slack-taut-slack changes under force control: every
  step converges, the slack line carries nothing, displacements match the piecewise closed
  form; a point whose lines are all slack under load is reported, not hidden;
- ropes over pulleys: one tension on both sides; unequal masses on a fixed pulley and a
  loaded pulley on a rope between unequal heights against their closed forms;
- bad input names the element and what was expected.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import brentq, fsolve

import jaxtube as jt
from jaxtube._elements.lines import (
    smoothed_ramp,
    smoothed_ramp_integral,
    tension,
    tension_only_energy,
)

G = 9.81


def test_smoothed_tension_law_error_bound_and_continuity():
    """Exact ``max(e, 0)`` outside ``|e| < delta / 2``; inside within ``delta / 8`` (reached
    at ``e = 0``); C1; the energy's derivative is the tension."""
    delta = 1e-3
    e = jnp.linspace(-3 * delta, 3 * delta, 2001)
    edges = jnp.asarray([-delta / 2 - 1e-12, -delta / 2 + 1e-12,
                         delta / 2 - 1e-12, delta / 2 + 1e-12])
    length = jnp.asarray([0.9, 1.0, 1.0 + 1e-5, 1.2])

    @jax.jit   # one compilation for every evaluation below
    def evaluate(e, edges, length):
        return dict(
            ramp=smoothed_ramp(e, delta),
            at_zero=smoothed_ramp(jnp.zeros(()), delta),
            slope_at_edges=jax.vmap(jax.grad(lambda x: smoothed_ramp(x, delta)))(edges),
            integral_slope=jax.vmap(jax.grad(lambda x: smoothed_ramp_integral(x, delta)))(e),
            du_dl=jax.vmap(jax.grad(lambda x: tension_only_energy(x, 50.0, 1.0, delta)))(length),
            tension=tension(length, 50.0, 1.0, delta),
        )

    out = {k: np.asarray(v) for k, v in evaluate(e, edges, length).items()}
    e, r = np.asarray(e), out["ramp"]
    exact = np.maximum(e, 0.0)
    outside = np.abs(e) >= delta / 2
    np.testing.assert_array_equal(r[outside & (e < 0)], 0.0)
    np.testing.assert_allclose(r[outside], exact[outside], atol=1e-18)
    assert np.abs(r - exact).max() <= delta / 8 * (1 + 1e-12)
    assert float(out["at_zero"]) == pytest.approx(delta / 8, rel=1e-12)
    # C1: the slope is continuous at both ends of the blend (0, then 1).
    np.testing.assert_allclose(out["slope_at_edges"], [0.0, 0.0, 1.0, 1.0], atol=1e-8)
    # R' = r, so the energy k L0^2 R(e) has dU/dl = tension.
    np.testing.assert_allclose(out["integral_slope"], r, atol=1e-15)
    np.testing.assert_allclose(out["du_dl"], out["tension"], rtol=1e-13)
    np.testing.assert_allclose(out["tension"][[0, 3]], [0.0, 50.0 * 0.2], rtol=1e-13)


def discrete_catenary(links, span, stiffness, rest_length, mass):
    """Node positions ``[links + 1, 2]`` (x, z) of a chain of ``links`` elastic links between
    two supports at equal height, with ``mass`` at each interior node: the horizontal
    tension ``H`` is constant and link ``i`` carries the vertical force ``V0 - i m g``;
    ``(H, V0)`` solve closure in x and z (scipy ``fsolve``)."""

    def steps(unknowns):
        horizontal, vertical0 = unknowns
        vertical = vertical0 - np.arange(links) * mass * G
        force = np.hypot(horizontal, vertical)
        length = rest_length + force / stiffness
        return np.stack([length * horizontal / force, -length * vertical / force], axis=1)

    def closure(unknowns):
        total = steps(unknowns).sum(axis=0)
        return [total[0] - span, total[1]]

    guess = [mass * G * links, 0.5 * (links - 1) * mass * G]
    solution = fsolve(closure, guess, xtol=1e-13)
    assert np.max(np.abs(closure(solution))) < 1e-13, "the reference solve did not converge"
    return np.concatenate([np.zeros((1, 2)), np.cumsum(steps(solution), axis=0)])


def taut_chain(prefix, links, span, stiffness, rest_length, mass, offset):
    """Points and lines of a chain between fixed points ``offset`` and ``offset + span x``,
    started taut: nodes at equal steps along a circular arc through the supports whose
    chords are 5 % longer than the rest length. Returns (points, lines, node names)."""
    chord = 1.05 * rest_length

    def mismatch(half):   # the arc's half-angle at which `links` such chords span it
        return links * np.arcsin(chord * np.sin(half) / span) - half

    half = brentq(mismatch, 1e-3, np.pi / 2)
    radius = span / (2 * np.sin(half))
    angle = np.linspace(-half, half, links + 1)
    x = 0.5 * span + radius * np.sin(angle)
    sag = radius * (np.cos(angle) - np.cos(half))
    names = [f"{prefix}{i}" for i in range(links + 1)]
    at = [np.asarray(offset) + [x[i], 0.0, -sag[i]] for i in range(links + 1)]
    points = [jt.FixedPoint(names[0], offset), jt.FixedPoint(names[-1], at[-1])]
    points += [jt.PointNode(names[i], at[i], mass=mass) for i in range(1, links)]
    lines = [jt.Line(names[i], names[i + 1], stiffness, rest_length) for i in range(links)]
    return points, lines, names


def test_hanging_chains_match_discrete_catenary():
    """Chains of 4 and 7 links (one structure, so one compilation) against the independent
    solve of the discrete catenary."""
    span, stiffness, mass = 1.0, 800.0, 0.05
    chains = {4: (0.0, 0.0, 0.0), 7: (3.0, 1.0, 0.5)}
    points, lines, names = [], [], {}
    for links, offset in chains.items():
        p, q, names[links] = taut_chain(f"c{links}_", links, span, stiffness,
                                        1.25 * span / links, mass, offset)
        points, lines = points + p, lines + q
    structure, params = jt.build_structure([], [], points=points, lines=lines)
    sol = jax.jit(lambda p: jt.equilibrium(structure, p))(params)
    jt.check_converged(sol)
    assert np.all(np.asarray(sol.line_taut))
    reaction = np.asarray(sol.fixed_point_reaction).reshape(2, 2, 3)   # chain, end, xyz
    for c, (links, offset) in enumerate(chains.items()):
        expected = discrete_catenary(links, span, stiffness, 1.25 * span / links, mass)
        order = [structure.node_id(name) for name in names[links]]
        position = np.asarray(sol.node_position)[order] - np.asarray(offset)
        np.testing.assert_allclose(position[:, [0, 2]], expected, atol=1e-10)
        np.testing.assert_allclose(position[:, 1], 0.0, atol=1e-12)
        # Supports carry the weight: each half of it, and the same horizontal tension.
        np.testing.assert_allclose(reaction[c, :, 2], 0.5 * (links - 1) * mass * G, rtol=1e-10)
        np.testing.assert_allclose(reaction[c, 0, 0], -reaction[c, 1, 0], rtol=1e-10)


SLACK_K, SLACK_L0, SLACK_FORCE = 100.0, 0.9, 40.0


@pytest.fixture(scope="module")
def slack_taut_path():
    """A point between fixed points 1 m above and below it, on two lines of rest length
    0.9 m (both taut at rest), loaded vertically by ``factor * 40 N`` up and down."""
    points = [jt.FixedPoint("top", (0.0, 0.0, 1.0)), jt.FixedPoint("bottom", (0.0, 0.0, -1.0)),
              jt.PointNode("P", (0.0, 0.0, 0.0), force=(0.0, 0.0, SLACK_FORCE))]
    lines = [jt.Line("top", "P", SLACK_K, SLACK_L0), jt.Line("P", "bottom", SLACK_K, SLACK_L0)]
    structure, params = jt.build_structure([], [], points=points, lines=lines, gravity=(0, 0, 0))
    # Up to +40 N (upper line slack), down to -40 N (lower line slack), back to 0; the
    # factors +-0.5 put a line exactly at its rest length, inside the blend.
    factors = np.concatenate([np.linspace(0, 1, 5), np.linspace(0.75, -1, 8), [-0.5, 0.0]])
    path = jt.ForceControl(factors)
    solve = jax.jit(lambda p: jt.solve_path(structure, p, path))
    return structure, params, factors, solve


def test_line_goes_slack_and_taut_again_and_slack_line_carries_nothing(slack_taut_path):
    structure, params, factors, solve = slack_taut_path
    sol = solve(params)
    jt.check_converged(sol, "slack-taut path")    # every step
    force = factors * SLACK_FORCE
    # Closed form: both taut while |F| < 2 k (1 - L0), then the far line alone.
    both = np.abs(force) < 2 * SLACK_K * (1 - SLACK_L0)
    up = np.where(both, force / (2 * SLACK_K),
                  np.where(force > 0, force / SLACK_K - (1 - SLACK_L0),
                           force / SLACK_K + (1 - SLACK_L0)))
    z = np.asarray(sol.point_position)[:, 2, 2]
    delta = float(params.elements.tension_smoothing)
    in_blend = np.isclose(np.abs(force), 2 * SLACK_K * (1 - SLACK_L0))
    assert in_blend.sum() == 4
    np.testing.assert_allclose(z[~in_blend], up[~in_blend], atol=1e-11)
    # At a slack-taut change the blend's tension error (<= k L0 delta / 8) moves the point
    # by at most L0 delta / 8.
    assert np.all(np.abs(z - up)[in_blend] <= SLACK_L0 * delta / 8 * (1 + 1e-9))
    assert np.all(np.abs(z - up)[in_blend] > 0.1 * SLACK_L0 * delta / 8)  # the blend is used

    tension = np.asarray(sol.line_tension)
    taut = np.asarray(sol.line_taut)
    upper_slack, lower_slack = force > 20.0 + 1e-9, force < -20.0 - 1e-9
    assert upper_slack.sum() >= 2 and lower_slack.sum() >= 2
    np.testing.assert_array_equal(tension[upper_slack, 0], 0.0)   # exactly nothing
    np.testing.assert_array_equal(tension[lower_slack, 1], 0.0)
    assert not taut[upper_slack, 0].any() and not taut[lower_slack, 1].any()
    assert taut[~upper_slack, 0].all() and taut[~lower_slack, 1].all()
    np.testing.assert_allclose(tension[~in_blend, 1] - tension[~in_blend, 0],
                               force[~in_blend], rtol=1e-10, atol=1e-9)
    reaction = np.asarray(sol.fixed_point_reaction).sum(axis=1)
    np.testing.assert_allclose(reaction[:, 2], -force, atol=1e-9)


def test_point_with_every_line_slack_under_load_is_reported(slack_taut_path):
    """Both lines longer than the gap: the loaded point has no stiffness and no equilibrium.
    The solve reports failure at every loaded step (never a false 'converged', never NaN
    positions); the unloaded step is a (neutral) equilibrium."""
    import equinox as eqx

    structure, params, factors, solve = slack_taut_path
    loose = eqx.tree_at(lambda p: p.elements.line_rest_length, params,
                        jnp.asarray([1.5, 1.5]))
    sol = solve(loose)
    converged = np.asarray(sol.converged)
    assert not converged[factors != 0].any()
    assert converged[factors == 0].all()
    assert np.all(np.isfinite(np.asarray(sol.point_position)))
    assert set(np.asarray(sol.result)[factors != 0]) <= {1, 2, 3}


def test_pulleys_one_tension_on_both_sides_against_closed_forms():
    """Two independent ropes in one structure.

    (a) Unequal masses on a fixed pulley: ``m1`` hangs free on one end; the other end holds
    ``m2 < m1`` and is tethered to the floor. The rope tension is ``m1 g`` on both sides,
    the tether carries ``(m1 - m2) g`` and the pulley's reaction is ``2 m1 g``.

    (b) A mass ``m`` on a free pulley riding a rope between anchors at unequal heights:
    equal tension means equal angles ``a`` on both sides; ``2 T sin a = m g`` and
    ``w / cos a = L0 + T / k`` (elastic rope) give ``a`` (scipy ``brentq``).
    """
    m1, m2, k, k_tether, rope = 3.0, 1.0, 2000.0, 500.0, 2.0
    w, h, m, k_b, rope_b = 2.0, 0.5, 4.0, 3000.0, 2.6
    points = [
        jt.FixedPoint("sheave", (0.0, 0.0, 3.0)),
        jt.FixedPoint("floor", (0.0, 0.0, 0.0)),
        jt.PointNode("heavy", (-0.02, 0.0, 1.9), mass=m1),
        jt.PointNode("light", (0.02, 0.0, 2.0), mass=m2),
        jt.FixedPoint("low anchor", (5.0, 0.0, 0.0)),
        jt.FixedPoint("high anchor", (5.0 + w, 0.0, h)),
        jt.PointNode("block", (5.0 + 0.4 * w, 0.0, -0.8), mass=m),
    ]
    pulleys = [jt.Pulley("heavy", "sheave", "light", k, rope),
               jt.Pulley("low anchor", "block", "high anchor", k_b, rope_b)]
    lines = [jt.Line("light", "floor", k_tether, 1.5)]
    structure, params = jt.build_structure([], [], points=points, lines=lines,
                                           pulleys=pulleys, gravity=(0.0, 0.0, -G))
    sol = jax.jit(lambda p: jt.equilibrium(structure, p))(params)
    jt.check_converged(sol)
    x = {name: np.asarray(sol.node_position)[structure.node_id(name)]
         for name in ("heavy", "light", "block")}
    tension = np.asarray(sol.pulley_tension)

    # (a)
    assert tension[0] == pytest.approx(m1 * G, rel=1e-10)
    assert float(sol.line_tension[0]) == pytest.approx((m1 - m2) * G, rel=1e-10)
    tether = 1.5 + (m1 - m2) * G / k_tether
    l2 = 3.0 - tether
    l1 = rope + m1 * G / k - l2
    np.testing.assert_allclose(x["light"], [0.0, 0.0, tether], atol=1e-10)
    np.testing.assert_allclose(x["heavy"], [0.0, 0.0, 3.0 - l1], atol=1e-10)
    sheave, floor = np.asarray(sol.fixed_point_reaction)[:2]
    np.testing.assert_allclose(sheave, [0.0, 0.0, 2 * m1 * G], atol=1e-8)
    np.testing.assert_allclose(floor, [0.0, 0.0, -(m1 - m2) * G], atol=1e-8)

    # (b)
    def mismatch(angle):
        return w / np.cos(angle) - rope_b - m * G / (2 * np.sin(angle)) / k_b

    angle = brentq(mismatch, 1e-3, np.pi / 2 - 1e-6, xtol=1e-15)
    t_b = m * G / (2 * np.sin(angle))
    assert tension[1] == pytest.approx(t_b, rel=1e-9)
    # Equal angles: the block sits where both rope segments make angle a with the horizontal.
    x_block = 5.0 + (w / np.cos(angle) * np.cos(angle) * 0.5
                     - 0.5 * h / np.tan(angle))
    z_block = -np.tan(angle) * (x_block - 5.0)
    np.testing.assert_allclose(x["block"], [x_block, 0.0, z_block], atol=1e-9)
    low, high = np.asarray(sol.fixed_point_reaction)[2:]
    assert np.linalg.norm(low) == pytest.approx(t_b, rel=1e-9)     # one tension, both sides
    assert np.linalg.norm(high) == pytest.approx(t_b, rel=1e-9)


def test_bad_elements_name_the_element_and_what_was_expected():
    fixed = jt.FixedPoint("A", (0, 0, 0))
    free = jt.PointNode("B", (1, 0, 0), mass=1.0)
    with pytest.raises(ValueError, match=r"line 0: end_b: no point named 'C'"):
        jt.build_structure([], [], points=[fixed, free], lines=[jt.Line("A", "C", 1.0)])
    with pytest.raises(ValueError, match=r"line 0 \('bridle'\): stiffness: expected a positive"):
        jt.build_structure([], [], points=[fixed, free],
                           lines=[jt.Line("A", "B", -5.0, name="bridle")])
    with pytest.raises(ValueError, match=r"belong to no line or pulley"):
        jt.build_structure([], [], points=[fixed, free])
    with pytest.raises(ValueError, match=r"duplicate point name 'A'"):
        jt.build_structure([], [], points=[fixed, jt.FixedPoint("A", (1, 1, 1))])
    with pytest.raises(ValueError, match=r"position \[m\]: expected 3 finite numbers"):
        jt.build_structure([], [], points=[jt.FixedPoint("A", (0, 0))])
    with pytest.raises(ValueError, match=r"pulley 0: the pulley node .* is also a rope end"):
        jt.build_structure([], [], points=[fixed, free], pulleys=[jt.Pulley("A", "B", "B", 1.0)])
    tube = jt.straight_tube("t", (0, 0, 0), (1, 0, 0), 2, 0.05, 2e4, jt.LinearLaw(10.0))
    with pytest.raises(ValueError, match=r"line 0: end_a: node 't:5' does not exist"):
        jt.build_structure([tube], [jt.Support("t:0")], points=[fixed],
                           lines=[jt.Line("t:5", "A", 1.0)])
    with pytest.raises(ValueError, match=r"tension_smoothing"):
        jt.build_structure([], [], points=[fixed, free], lines=[jt.Line("A", "B", 1.0)],
                           tension_smoothing=0.0)
