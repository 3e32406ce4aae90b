"""Tubes sharing a law form are evaluated together (``jaxtube/_mechanics/law_groups.py``):
the energy, the joint moments and the assembled Hessian equal those of each joint's own
tube law, evaluated joint by joint, on a frame of three tubes with two law forms, different
parameters and different pressures."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

import jaxtube as jt
from jaxtube._mechanics import (
    energy_and_constraints,
    joint_moments,
    reference_geometry,
    spring_joints,
)
from jaxtube._mechanics.law_groups import law_groups

from .test_solver import assert_assembled_hessian_is_exact


def _frame():
    """A post, a beam and a brace: the first two with linear laws of different stiffness
    (one group of two tubes, stacked), the brace with Breukels' 2011 law scaled (a group of
    its own); three pressures."""
    post = jt.straight_tube("post", (0, 0, 0), (0, 0, 1.0), 4, 0.05, 2e4, jt.LinearLaw(30.0),
                            torsion_law=jt.LinearLaw(20.0))
    beam = jt.straight_tube("beam", (0, 0, 1.0), (0.8, 0.1, 1.0), 4, 0.04, 3e4,
                            jt.LinearLaw(25.0), torsion_law=jt.LinearLaw(12.0))
    brace = jt.straight_tube("brace", (0, 0, 0.5), (0.4, 0.05, 1.0), 3, 0.06, 1.5e4,
                             jt.ScaledLaw(jt.EmpiricalBendingLaw2011(), 0.4),
                             torsion_law=jt.EmpiricalTorsionLaw2011())
    return jt.build_structure(
        [post, beam, brace], [jt.Support("post:0", "clamped")],
        [jt.Connection("post:end", "beam:0"), jt.Connection("post:2", "brace:0")],
        node_force={"beam:end": [0.0, 0.0, -4.0]})


def _random_state(structure, params, seed, scale=0.2):
    state0 = jt.initial_state(structure, params)
    z0, unravel = ravel_pytree(state0)
    rng = np.random.default_rng(seed)
    return z0 + scale * jnp.asarray(rng.standard_normal(z0.shape)), unravel


def test_tubes_group_by_law_form():
    structure, params = _frame()
    joints = spring_joints(structure, reference_geometry(structure, params),
                           jt.initial_state(structure, params))
    groups = law_groups(joints.law_tube, params.bending_laws, params.torsion_laws)
    assert len(groups) == 2
    tubes = [sorted(set(np.asarray(g.tubes).tolist())) for g in groups]
    assert tubes == [[0, 1], [2]]
    assert not groups[0].one_tube and groups[1].one_tube
    every = np.sort(np.concatenate([g.joints for g in groups]))
    np.testing.assert_array_equal(every, np.arange(len(joints.law_tube)))


def test_grouped_energy_and_moments_equal_each_joints_own_law():
    structure, params = _frame()
    geometry = reference_geometry(structure, params)
    z, unravel = _random_state(structure, params, 0)
    state = unravel(z)
    joints = spring_joints(structure, geometry, state)
    radius = params.node_radius[np.asarray(joints.node)]
    energy, moments = 0.0, []
    for j, tube in enumerate(joints.law_tube):
        kappa = joints.rotation[j] / joints.tributary[j]
        bending, torsion = params.bending_laws[tube], params.torsion_laws[tube]
        pressure = params.pressure[tube]
        bend = jnp.sqrt(kappa[0] ** 2 + kappa[1] ** 2)
        energy += joints.tributary[j] * (
            bending.energy_density(bend**2, pressure, radius[j])
            + torsion.energy_density(kappa[2] ** 2, pressure, radius[j]))
        moments.append(jnp.concatenate([bending.moment(bend, pressure, radius[j]) / bend
                                        * kappa[:2],
                                        torsion.moment(kappa[2], pressure, radius[j])[None]]))
    unloaded = eqx.tree_at(lambda p: p.node_force, params, jnp.zeros_like(params.node_force))
    total = energy_and_constraints(structure, geometry, state, unloaded, None)[0]
    np.testing.assert_allclose(total, energy, rtol=1e-13)
    grouped, _ = joint_moments(joints, params)
    np.testing.assert_allclose(grouped, jnp.stack(moments), rtol=1e-12, atol=1e-14)


def test_grouped_hessian_equals_autodiff_hessian():
    structure, params = _frame()
    assert_assembled_hessian_is_exact(structure, params, None, seed=2)
