"""A tube frame hung by lines and a pulley bridle from two fixed points (no support), and the
exact Lagrangian Hessian with point nodes, lines, pulleys and masses (issue 14).

- along a force-controlled path, the fixed points' reactions balance the tube's
  self-weight, the point masses and the applied loads: forces and moments about the
  origin, every step;
- implicit gradients of hung node positions w.r.t. a line's rest length, the pulley rope's
  rest length, a line stiffness and the tube pressure against central finite differences;
- the element-assembled Hessian equals ``jax.hessian`` of ``E + lambda . c`` (the pattern
  of ``tests/test_solver.py``) on a clamped mast with lines, a pulley, masses, a fixed
  point, a point joined to a tube node and displacement control of a point node.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxtube as jt
from jaxtube._mechanics import reference_geometry

G = 9.81
MASS_PER_LENGTH, NODE_MASS, BALLAST = 0.2, 0.2, 0.3
FACTORS = np.array([0.5, 1.0, 1.5])


def hung_arch():
    """A U-shaped arch (8 segments, r = 40 mm, 0.2 bar) hanging from fixed points L and R:
    its left end and a second node through a rope over a pulley point hung from L, its
    right end by a line from R; a ballast point hangs from the bottom node. Breukels' 2011
    law, whose bending stiffness grows with the pressure (a tension-field tube's does not
    before it wrinkles, which would leave the pressure gradient zero)."""
    law = jt.EmpiricalBendingLaw2011()
    arch = jt.arc_tube("arch", (0, 0, 0), 0.5, np.pi, 2 * np.pi, 8, 0.04, 2e4, law,
                       torsion_law=jt.LinearLaw(20.0), normal=(0, -1, 0),
                       mass_per_length=MASS_PER_LENGTH)
    points = [jt.FixedPoint("L", (-0.6, 0.0, 1.0)), jt.FixedPoint("R", (0.6, 0.0, 1.0)),
              jt.PointNode("bridle", (-0.55, 0.0, 0.4)),
              jt.PointNode("ballast", (0.05, 0.0, -0.8), mass=BALLAST)]
    lines = [jt.Line("L", "bridle", 3000.0), jt.Line("R", "arch:end", 2000.0),
             jt.Line("arch:4", "ballast", 1500.0)]
    pulleys = [jt.Pulley("arch:0", "bridle", "arch:2", 2500.0, name="bridle rope")]
    return jt.build_structure(
        [arch], [], points=points, lines=lines, pulleys=pulleys,
        point_masses=[jt.PointMass("arch:4", NODE_MASS)],
        node_force={"arch:6": [1.0, 0.5, -2.0]})


@pytest.fixture(scope="module")
def hung():
    structure, params = hung_arch()
    path = jt.ForceControl(FACTORS)
    # Point positions are absolute coordinates, so the stopping rule's scale (which includes
    # |H z|, about k |x| ~ 1e3-1e4 N here) lets the default rtol stop at force residuals near
    # 1e-7 N; the finite differences below need tighter solves.
    solver = jt.NewtonKKT(rtol=1e-13)
    solve = jax.jit(lambda p: jt.solve_path(structure, p, path, solver))
    return structure, params, solve


def test_suspension_reactions_balance_weight_and_loads(hung):
    structure, params, solve = hung
    assert structure.supports == ()        # held by lines only: the root floats
    sol = solve(params)
    jt.check_converged(sol, "hung arch")
    assert np.all(np.asarray(sol.line_taut)) and np.all(np.asarray(sol.pulley_taut))
    g = np.array([0.0, 0.0, -G])
    reference = np.asarray(params.node_position)
    segments = np.array(structure.segment_nodes)
    segment_weight = (MASS_PER_LENGTH * np.linalg.norm(
        reference[segments[:, 1]] - reference[segments[:, 0]], axis=1))[:, None] * g
    bottom, loaded = structure.node_id("arch:4"), structure.node_id("arch:6")
    ballast = structure.node_id("ballast")
    anchors = np.array([[-0.6, 0.0, 1.0], [0.6, 0.0, 1.0]])
    for k, factor in enumerate(FACTORS):
        x = np.asarray(sol.node_position[k])
        midpoint = 0.5 * (x[segments[:, 0]] + x[segments[:, 1]])
        applied = factor * np.array([1.0, 0.5, -2.0])
        forces = np.concatenate([segment_weight, [NODE_MASS * g, BALLAST * g, applied]])
        where = np.concatenate([midpoint, x[[bottom, ballast, loaded]]])
        reaction = np.asarray(sol.fixed_point_reaction[k])
        total = forces.sum(0) + reaction.sum(0)
        moment = np.cross(where, forces).sum(0) + np.cross(anchors, reaction).sum(0)
        scale = np.abs(forces).sum()
        # To solver tolerance: the imbalance is a sum of KKT force residuals (each at most
        # the reported residual), over 3 translations of the root and of every point.
        residual = float(sol.residual[k])
        assert residual < 1e-9 * scale
        rows = 3 * (1 + structure.elements.unknown_count)
        np.testing.assert_allclose(total, 0.0, atol=rows * residual + 1e-13 * scale)
        lever = np.max(np.abs(np.concatenate([x, anchors])))   # force residual x lever arm
        moment_rows = rows * lever + 3 * structure.segment_count  # + joint moment residuals
        np.testing.assert_allclose(moment, 0.0, atol=moment_rows * residual + 1e-13 * scale)
        # The bridle rope pulls its two tube nodes with one tension.
        rope = float(sol.pulley_tension[k, 0])
        attached = list(structure.elements.attachment_nodes)
        ends = [attached.index(structure.node_id(n)) for n in ("arch:0", "arch:2")]
        pulls = np.linalg.norm(np.asarray(sol.attachment_force[k])[ends], axis=1)
        np.testing.assert_allclose(pulls, rope, rtol=1e-9)
    assert float(sol.node_position[-1][loaded][1]) > 1e-3    # the side load swings it out


def test_hung_positions_gradients_match_central_differences(hung):
    structure, params, solve = hung
    bottom, ballast = structure.node_id("arch:4"), structure.node_id("ballast")

    def hung_positions(p):
        x = solve(p).node_position[-1]
        return jnp.concatenate([x[bottom], x[ballast]])

    directions = {   # (leaf, index): line 1 is the line from R, pulley 0 the bridle rope
        "rest length of the line from R": (lambda p: p.elements.line_rest_length, 1),
        "rest length of the bridle rope": (lambda p: p.elements.pulley_rest_length, 0),
        "stiffness of the line from R": (lambda p: p.elements.line_stiffness, 1),
        "tube pressure": (lambda p: p.pressure, 0),
    }
    tangent_fn = jax.jit(lambda p, dp: jax.jvp(hung_positions, (p,), (dp,))[1])
    zero = jax.tree.map(jnp.zeros_like, params)
    for name, (where, index) in directions.items():
        value = where(params)
        unit = jnp.zeros_like(value).at[index].set(1.0)
        step = 1e-6 * float(jnp.abs(value[index]))
        plus = np.asarray(hung_positions(eqx.tree_at(where, params, value + step * unit)))
        minus = np.asarray(hung_positions(eqx.tree_at(where, params, value - step * unit)))
        finite = (plus - minus) / (2 * step)
        implicit = np.asarray(tangent_fn(params, eqx.tree_at(where, zero, unit)))
        # A sensitivity that matters: a 100 % change would move a node by over 1 mm.
        assert np.max(np.abs(finite)) * float(jnp.abs(value[index])) > 1e-3, name
        np.testing.assert_allclose(implicit, finite, rtol=1e-5,
                                   atol=1e-5 * np.max(np.abs(finite)), err_msg=name)


def test_assembled_hessian_with_elements_equals_autodiff_hessian():
    """At random states (lines taut, in the blend and slack) and random multipliers."""
    from jax.flatten_util import ravel_pytree

    from jaxtube._model import _objective, lagrangian_hessian

    mast = jt.straight_tube("mast", (0, 0, 0), (0.1, 0.0, 1.0), 4, 0.05, 2e4,
                            jt.LinearLaw(30.0), torsion_law=jt.LinearLaw(20.0),
                            mass_per_length=0.3)
    points = [jt.FixedPoint("anchor", (1.0, 0.2, 0.0)),
              jt.PointNode("kite", (0.6, 0.1, 1.3), mass=0.4, force=(1.0, 0.0, 2.0)),
              jt.PointNode("block", (0.6, -0.1, 0.5), mass=0.2),
              jt.PointNode("on mast", at="mast:2", mass=0.1)]
    lines = [jt.Line("mast:end", "kite", 500.0), jt.Line("kite", "anchor", 800.0, 1.2),
             jt.Line("on mast", "kite", 300.0)]
    pulleys = [jt.Pulley("mast:3", "block", "anchor", 700.0)]
    structure, params = jt.build_structure(
        [mast], [jt.Support("mast:0", "clamped")], points=points, lines=lines,
        pulleys=pulleys, point_masses=[jt.PointMass("mast:1", 0.3)], tension_smoothing=0.05)
    assert structure.node_id("on mast") == structure.node_id("mast:2")
    control = (structure.node_id("kite"), jnp.array([1.0, 0.0, 0.0]), 0.02)
    geometry = reference_geometry(structure, params)
    state0 = jt.initial_state(structure, params)
    z0, unravel = ravel_pytree(state0)
    m = _objective(structure, geometry, state0, params, control)[1].shape[0]

    def lagrangian(zz, lam):
        energy, c = _objective(structure, geometry, unravel(zz), params, control)
        return energy + lam @ c

    autodiff = jax.jit(jax.hessian(lagrangian))
    assemble = jax.jit(lambda zz, lam: lagrangian_hessian(structure, geometry, params, control,
                                                          unravel(zz), lam))
    report = jax.jit(lambda zz: jt._elements.line_report(
        structure.elements, params.elements, unravel(zz)["point_position"]))
    rng = np.random.default_rng(14)
    branches = set()
    for scale in (0.0, 0.05, 0.3):
        z = z0 + scale * jnp.asarray(rng.standard_normal(z0.shape))
        lam = jnp.asarray(rng.standard_normal(m)) * 10.0
        strain = np.concatenate([
            np.asarray(report(z)["line_length"]) / np.asarray(params.elements.line_rest_length),
            np.asarray(report(z)["pulley_length"])
            / np.asarray(params.elements.pulley_rest_length)]) - 1.0
        branches |= set(np.digitize(strain, [-0.025, 0.025]).tolist())
        expected = autodiff(z, lam)
        assembled = assemble(z, lam)
        assert np.all(np.isfinite(assembled))
        np.testing.assert_allclose(assembled, expected, rtol=1e-9,
                                   atol=1e-9 * float(jnp.max(jnp.abs(expected))))
    assert branches == {0, 1, 2}, "the states must cover slack, blended and taut lines"
