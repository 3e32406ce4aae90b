"""The exact Hessian of the Lagrangian, assembled from element Hessians.

With segment rotations as unknowns every load and constraint is a sum of per-segment terms
and every spring couples only its two segments, so the Hessian of
``L = E + lambda . c`` is block-sparse along the joints (see :func:`lagrangian_hessian`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .._elements import dense_from_blocks, element_hessian_blocks, state_index
from .._rotation import (
    inverse_right_jacobian_transpose,
    matvec3,
    right_jacobian,
    rotation_matrix,
    transpose3,
)
from .._structure.structure import Structure
from .energy import constraints, load_potential, shear_stiffness
from .geometry import ReferenceGeometry
from .kinematics import (
    Configuration,
    positions_from_steps,
    relative_joint_rotation,
    segment_steps,
)
from .law_groups import law_groups


def lagrangian_hessian(structure: Structure, geometry: ReferenceGeometry, params, control,
                       state: dict, multipliers: Array) -> Array:
    """Hessian of ``L = E + lambda . c`` w.r.t. the flattened state, ``[n, n]``: the blocks
    of :func:`lagrangian_hessian_blocks` scatter-added into a dense matrix."""
    return dense_from_blocks(state, lagrangian_hessian_blocks(structure, geometry, params,
                                                              control, state, multipliers))


def lagrangian_hessian_blocks(structure: Structure, geometry: ReferenceGeometry, params,
                              control, state: dict, multipliers: Array) -> list:
    """Hessian of ``L = E + lambda . c`` w.r.t. the flattened state as a list of blocks
    ``(rows, cols, values)`` (static index arrays and element Hessians: the interface of
    ``jaxtube._solver.kkt_linear``), the exact Hessian, not an approximation.

    Node positions are ``root + sum_s Q_s0 exp(phi_s) e_s`` and every load potential and
    constraint is linear in the root position and the segment vectors ``step_s``, so with
    ``g_s = dL/dstep_s`` (one reverse pass) the position part contributes a 3 x 3 block
    ``d^2/dphi_s^2 [g_s . Q_s0 exp(phi_s) e_s]`` per segment (5 x 5 over ``(phi_s,
    gamma_s)`` with shear, whose energy is per segment too); each spring joint contributes a
    6 x 6 block over the rotations of its two segments; torques are linear in ``phi``. The
    blocks come from ``jax.hessian`` of these small element functions (the joints': the
    forward-mode Jacobian of their gradient in closed form, ``docs/physics.md`` section
    1.5), vmapped, and are scatter-added at static indices. Cost grows linearly with the
    segment count (the dense autodiff Hessian grows quadratically and pushes every unknown
    through the chain).
    Lines and pulleys add 6 x 6 and 9 x 9 blocks over their point nodes
    (``jaxtube._elements.element_hessian_blocks``); attachment ties are linear in the
    segment vectors and enter through ``g_s``.
    """
    if not structure.segment_count:
        return _element_blocks(structure, params, state)
    phi = state["segment_rotation"]
    frame, step = segment_steps(geometry, state)

    def linear_part(step):
        start, end, nodes = positions_from_steps(structure, state["root_position"], step)
        config = Configuration(frame=frame, segment_start=start, segment_end=end,
                               node_position=nodes)
        potential = load_potential(structure, geometry, config, params, state)
        return potential + jnp.dot(multipliers,
                                   constraints(structure, config, state, params, control))

    step_force = jax.grad(linear_part)(step)
    body_force = matvec3(transpose3(geometry.frame), step_force)

    index = state_index(state)
    rotation_index = index["segment_rotation"]  # [S, 3] positions in the flat state

    if "segment_shear" in state:
        # Element of segment s over (phi_s, gamma_s): position term plus shear energy.
        stiffness = shear_stiffness(structure, params) * geometry.length

        def segment_term(dofs, force_s, end_s, length_s, stiffness_s):
            vector = end_s + length_s * jnp.concatenate([dofs[3:], jnp.zeros(1)])
            return (force_s @ (rotation_matrix(dofs[:3]) @ vector)
                    + 0.5 * stiffness_s * jnp.sum(dofs[3:] ** 2))

        dofs = jnp.concatenate([phi, state["segment_shear"]], axis=1)
        segment_blocks = jax.vmap(jax.hessian(segment_term))(
            dofs, body_force, geometry.end_vector, geometry.length, stiffness)
        segment_index = np.concatenate([rotation_index, index["segment_shear"]], axis=1)
    else:
        def segment_term(phi_s, force_s, end_s):
            return force_s @ (rotation_matrix(phi_s) @ end_s)

        segment_blocks = jax.vmap(jax.hessian(segment_term))(phi, body_force,
                                                             geometry.end_vector)
        segment_index = rotation_index
    rows = [np.broadcast_to(segment_index[:, :, None], segment_blocks.shape)]
    cols = [np.broadcast_to(segment_index[:, None, :], segment_blocks.shape)]
    values = [segment_blocks]

    topology = structure.spring_joint_topology()
    parent, child = topology.parent_segment, topology.child_segment
    nodes, law = topology.node, topology.law
    # One Hessian of the joint energy per group of tubes sharing a law form, not per tube
    # (law_groups: the law's leaves taken per joint).
    for group in law_groups(law, params.bending_laws, params.torsion_laws):
        idx = group.joints

        def joint_energy_gradient(pair, parent_map, child_map, grounded, tributary, radius,
                                  bending, torsion, pressure):
            """``d W / d (phi_a, phi_b)`` ``[6]`` of one joint, in closed form
            (``docs/physics.md`` section 1.5); its forward-mode Jacobian is the joint's
            Hessian block, exact, and cheaper than ``jax.hessian`` of ``W(log(exp(-u)
            exp(v)))``."""
            u, v = parent_map @ pair[:3], child_map @ pair[3:]
            theta = relative_joint_rotation(pair[:3], pair[3:], parent_map, child_map, grounded)

            def energy(theta):
                kappa = theta / tributary
                w = bending.energy_density(kappa[0] ** 2 + kappa[1] ** 2, pressure, radius)
                return tributary * (w + torsion.energy_density(kappa[2] ** 2, pressure, radius))

            g = jax.grad(energy)(theta)
            moment = inverse_right_jacobian_transpose(theta) @ g
            d_v = jnp.where(grounded, g, right_jacobian(v).T @ moment)
            d_u = jnp.where(grounded, 0.0, -(right_jacobian(-u).T @ (rotation_matrix(v) @ moment)))
            return jnp.concatenate([parent_map.T @ d_u, child_map.T @ d_v])

        a, b = np.maximum(parent[idx], 0), child[idx]
        pair = jnp.concatenate([phi[a], phi[b]], axis=1)
        radius = params.node_radius[np.array([nodes[j] for j in idx], dtype=np.int32)]
        axis = group.law_axis
        blocks = jax.vmap(jax.jacfwd(joint_energy_gradient), in_axes=(0,) * 6 + (axis,) * 3)(
            pair, geometry.joint_parent_map[idx], geometry.joint_child_map[idx],
            parent[idx] == -1, geometry.joint_tributary[idx], radius,
            group.law(params.bending_laws), group.law(params.torsion_laws),
            group.per_joint(params.pressure))
        pair_index = np.concatenate([rotation_index[a], rotation_index[b]], axis=1)  # [Jg, 6]
        rows.append(np.broadcast_to(pair_index[:, :, None], blocks.shape))
        cols.append(np.broadcast_to(pair_index[:, None, :], blocks.shape))
        values.append(blocks)

    return list(zip(rows, cols, values)) + _element_blocks(structure, params, state)


def _element_blocks(structure, params, state) -> list:
    """Hessian blocks ``(rows, cols, values)`` of the lines and pulleys."""
    if not structure.elements.active:
        return []
    return element_hessian_blocks(structure.elements, params.elements,
                                  state["point_position"], state_index(state)["point_position"])
