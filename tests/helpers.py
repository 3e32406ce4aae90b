"""Shared test helpers: standard structures and finite differences."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

import jaxtube as jt


def with_tip_force(structure, params, force, node="tube:end"):
    """Parameters with a dead point force ``force [3]`` [N] at ``node``."""
    tip = structure.node_id(node)
    return eqx.tree_at(
        lambda p: p.node_force, params, params.node_force.at[tip].set(jnp.asarray(force, float))
    )


def central_difference(fn, x, rel_step=1e-6):
    """Central finite difference of scalar ``fn`` at scalar ``x``."""
    h = rel_step * max(abs(x), 1e-3)
    return (fn(x + h) - fn(x - h)) / (2 * h)


def linear_cantilever(segments, stiffness=1.0, torsion=0.8, length=1.0, direction=(1, 0, 0),
                      tip_torque=False):
    """Linear-law cantilever clamped at the origin; ``tip_torque`` declares a tip torque."""
    if not tip_torque:
        return jt.cantilever(
            length, 0.05, 1e4, segments, jt.LinearLaw(stiffness), jt.LinearLaw(torsion),
            direction=direction,
        )
    axis = np.asarray(direction, float) / np.linalg.norm(direction)
    tube = jt.straight_tube("tube", np.zeros(3), length * axis, segments, 0.05, 1e4,
                            jt.LinearLaw(stiffness), torsion_law=jt.LinearLaw(torsion))
    return jt.build_structure([tube], [jt.Support("tube:0", "clamped")],
                              node_torque={"tube:end": [0.0, 0.0, 0.0]})


def rotation_about(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.asarray(jt.rotation_matrix(jnp.asarray(axis * angle)))
