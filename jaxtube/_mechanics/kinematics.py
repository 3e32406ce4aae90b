"""Deformed configuration from the state: frames, positions and the spring joints' rotations.

State ``{"root_position": [3] m, "segment_rotation": [S, 3] rad}`` (plus ``"segment_shear":
[S, 2]`` with shear); ``Q_s = Q_s0 exp(phi_s)`` and each joint's rotation is
``exp(theta) = exp(-H_pre^T phi_a) exp(H_post phi_b)`` (see :mod:`jaxtube._mechanics`).
Node positions are sums of per-segment terms, linear in the root position and the segment
vectors.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array

from .._elements import initial_point_position
from .._rotation import matmul3, matvec3, rotation_matrix, rotation_vector
from .._structure.structure import GROUND, Structure, StructureParameters
from .geometry import ReferenceGeometry, take_rows


class Configuration(eqx.Module):
    """Deformed configuration. Shapes: ``S`` segments, ``N`` nodes."""

    frame: Array  # [S, 3, 3] deformed material frames Q_s = Q_s0 exp(phi_s)
    segment_start: Array  # [S, 3] m
    segment_end: Array  # [S, 3] m
    node_position: Array  # [N, 3] m


def initial_state(structure: Structure, params: StructureParameters) -> dict:
    """The undeformed state: zero segment rotations (and shear strains), root at its
    reference position; point nodes (``"point_position"`` ``[P, 3]``, when the structure
    has any) at their reference positions. A structure without tubes has only points."""
    state = {}
    if structure.segment_count:
        state["root_position"] = params.node_position[structure.root_node]
        state["segment_rotation"] = jnp.zeros((structure.segment_count, 3))
    if structure.shear:
        state["segment_shear"] = jnp.zeros((structure.segment_count, 2))
    if structure.elements.active:
        state["point_position"] = initial_point_position(
            structure.elements, params.elements, params.node_position)
    return state


def _position_sum_matrix(structure: Structure) -> np.ndarray:
    """``A[s, k] = 1`` when segment ``k`` lies on the position path from the root to the end
    of segment ``s`` (``s`` included), so that ``segment_end = root + A @ step``."""
    count = structure.segment_count
    matrix = np.zeros((count, count))
    for s in range(count):  # BFS order: a parent's row is complete before its children's
        p = structure.position_parent[s]
        if p != GROUND:
            matrix[s] = matrix[p]
        matrix[s, s] = 1.0
    return matrix


def segment_vector(geometry: ReferenceGeometry, state: dict) -> Array:
    """Start -> end of each segment in its material frame ``[S, 3]`` [m]: ``e_s`` plus, with
    shear, ``L_s (gamma_1, gamma_2, 0)`` (Timoshenko kinematics: the section turns with
    ``Q_s``, the axis shears by ``gamma``)."""
    if "segment_shear" not in state:
        return geometry.end_vector
    gamma = state["segment_shear"]
    transverse = jnp.concatenate([gamma, jnp.zeros_like(gamma[:, :1])], axis=1)
    return geometry.end_vector + geometry.length[:, None] * transverse


def segment_steps(geometry: ReferenceGeometry, state: dict) -> tuple[Array, Array]:
    """Deformed frames ``Q_s = Q_s0 exp(phi_s)`` ``[S, 3, 3]`` and the world vectors from each
    segment's kinematic start to its end ``[S, 3]`` [m]."""
    frame = matmul3(geometry.frame, rotation_matrix(state["segment_rotation"]))
    return frame, matvec3(frame, segment_vector(geometry, state))


def positions_from_steps(structure: Structure, root_position: Array, step: Array):
    """Segment starts and ends ``[S, 3]`` and node positions ``[N, 3]``, all linear in
    ``(root_position [3], step [S, 3])``."""
    if _is_chain(structure):
        offset = jnp.cumsum(step, axis=0)
    else:
        offset = jnp.asarray(_position_sum_matrix(structure), step.dtype) @ step
    segment_end = root_position + offset
    segment_start = segment_end - step
    node_segment = np.array(structure.node_segment, dtype=np.int32)
    node_position = jnp.where(
        (node_segment >= 0)[:, None], take_rows(segment_end, np.maximum(node_segment, 0)),
        root_position,
    )
    return segment_start, segment_end, node_position


def _is_chain(structure: Structure) -> bool:
    return all(p == s - 1 for s, p in enumerate(structure.position_parent))


def configuration(structure: Structure, geometry: ReferenceGeometry, state: dict) -> Configuration:
    """Deformed frames and positions from the state (vectorised over segments)."""
    frame, step = segment_steps(geometry, state)
    start, end, nodes = positions_from_steps(structure, state["root_position"], step)
    return Configuration(frame=frame, segment_start=start, segment_end=end, node_position=nodes)


class JointSet(eqx.Module):
    """All springs in one flat list: tree joints with springs, then derived joints."""

    rotation: Array  # [J, 3] rad, joint frame
    tributary: Array  # [J] m
    post: Array  # [J, 3, 3] joint frame -> frame of ``frame_segment`` (H_post)
    node: tuple[int, ...] = eqx.field(static=True)  # [J] node of each joint
    law_tube: tuple[int, ...] = eqx.field(static=True)  # [J] tube whose law applies
    frame_segment: tuple[int, ...] = eqx.field(static=True)  # [J] segment giving the frame


def relative_joint_rotation(parent_rotation: Array, child_rotation: Array,
                            parent_map: Array, child_map: Array, grounded) -> Array:
    """Joint rotation vector ``theta = log(exp(-U phi_a) exp(V phi_b))`` [rad], ``[..., 3]``.

    From ``Q_s = Q_s0 exp(phi_s)`` and ``exp(theta) = H_pre^T Q_a^T Q_b H_post^T`` with the
    reference split ``Q_a0^T Q_b0 = H_pre H_post``: ``U = H_pre^T``, ``V = H_post``. A joint
    to the ground (``grounded``) has ``theta = V phi_b`` exactly.
    """
    u = matvec3(parent_map, parent_rotation)
    v = matvec3(child_map, child_rotation)
    coupled = rotation_vector(matmul3(rotation_matrix(-u), rotation_matrix(v)))
    return jnp.where(grounded, v, coupled)


def spring_joints(structure: Structure, geometry: ReferenceGeometry, state: dict) -> JointSet:
    """Every joint that carries a spring (free, pinned joints are left out), with its
    rotation from the two segment rotations it connects."""
    topology = structure.spring_joint_topology()
    parent, child = topology.parent_segment, topology.child_segment
    node, law = topology.node, topology.law
    phi = state["segment_rotation"]
    grounded = (parent == GROUND)[:, None]
    rotation = relative_joint_rotation(
        take_rows(phi, np.maximum(parent, 0)), take_rows(phi, child),
        geometry.joint_parent_map, geometry.joint_child_map, grounded)
    return JointSet(
        rotation=rotation,
        tributary=geometry.joint_tributary,
        post=geometry.joint_child_map,
        node=node,
        law_tube=law,
        frame_segment=tuple(int(s) for s in child),
    )
