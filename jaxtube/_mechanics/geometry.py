"""Reference geometry of a structure: material frames, segment lengths, joint splits.

Frames come by parallel transport along the kinematic tree; each spring joint's reference
relative rotation is split into ``H_pre H_post`` at the joint frame (the bisector for a bend
between two segments of one tube, the attached tube's frame at an attachment) and its
tributary length is set (docs/physics.md, section 1.2). Everything is differentiable in the
reference node positions.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .._rotation import matmul3, matvec3, minimal_rotation, transpose3
from .._structure.structure import (
    GROUND,
    JOINT_ATTACH,
    JOINT_BEND,
    Structure,
    StructureParameters,
)

_E3 = np.array([0.0, 0.0, 1.0])


def take_rows(values: Array, index) -> Array:
    """``values[index]`` for a static integer ``index`` along axis 0, without a gather.

    Reverse-mode differentiation turns a gather into a scatter-add, which XLA runs very
    slowly on CPU (and it sits inside every Hessian). An index made of a few runs of
    consecutive rows (a tube's joints, a chain's node positions) becomes slices;
    any other index a product with a constant one-hot matrix, whose transpose is another
    small dense product.
    """
    index = np.asarray(index, dtype=np.int64).reshape(-1)
    if index.size == 0:
        return values[:0]
    breaks = np.flatnonzero(np.diff(index) != 1) + 1
    starts = np.concatenate([[0], breaks])
    stops = np.concatenate([breaks, [index.size]])
    if len(starts) <= 8:
        pieces = [values[int(index[a]) : int(index[a]) + int(b - a)] for a, b in zip(starts, stops)]
        return pieces[0] if len(pieces) == 1 else jnp.concatenate(pieces, axis=0)
    one_hot = np.zeros((index.size, values.shape[0]), dtype=np.float64)
    one_hot[np.arange(index.size), index] = 1.0
    return jnp.tensordot(jnp.asarray(one_hot, dtype=values.dtype), values, axes=1)


def compose_along_tree(local: Array, parents: tuple[int, ...], combine, identity: Array) -> Array:
    """Prefix composition from the root: ``out[s] = combine(out[parent[s]], local[s])``.

    ``identity`` is the ground's value. Segments are in BFS order (parents first), so one
    ``lax.scan`` over them suffices. Shapes ``[S, ...] -> [S, ...]``. (A log-depth pointer
    jumping variant was measured 4x slower inside the Hessian on CPU: its extra rounds of
    batched work outweigh the shorter dependency chain at these sizes.)
    """
    count = len(parents)
    parent_index = jnp.asarray(np.array([count if p == GROUND else p for p in parents]),
                               dtype=jnp.int32)
    values0 = jnp.concatenate([jnp.zeros_like(local), identity[None]], axis=0)

    def step(values, inputs):
        index, own, parent = inputs
        composed = combine(values[parent], own)
        return values.at[index].set(composed), None

    values, _ = jax.lax.scan(
        step, values0, (jnp.arange(count, dtype=jnp.int32), local, parent_index)
    )
    return values[:count]


def _tangent_frame(tangent: Array) -> Array:
    """A right-handed frame ``[d1 d2 d3]`` (columns) with ``d3 = tangent``; ``[S,3]->[S,3,3]``."""
    up = jnp.where(
        (jnp.abs(tangent[:, 2]) > 0.9)[:, None], jnp.array([1.0, 0.0, 0.0]),
        jnp.array([0.0, 0.0, 1.0]),
    )
    d1 = up - jnp.sum(up * tangent, axis=-1, keepdims=True) * tangent
    d1 = d1 / jnp.linalg.norm(d1, axis=-1, keepdims=True)
    d2 = jnp.cross(tangent, d1)
    return jnp.stack([d1, d2, tangent], axis=-1)


class ReferenceGeometry(eqx.Module):
    """Reference quantities derived (differentiably) from the reference node positions.

    Shapes: ``S`` segments, ``J`` spring joints (tree joints with a spring, then derived
    joints), in the order of :class:`JointSet`.
    """

    frame: Array  # [S, 3, 3] reference material frames Q_s0 (columns d1, d2, d3 = tube axis)
    length: Array  # [S] m
    end_vector: Array  # [S, 3] kinematic start -> end in the segment's material frame, m
    joint_parent_map: Array  # [J, 3, 3] U_j: parent segment rotation -> joint frame (0: ground)
    joint_child_map: Array  # [J, 3, 3] V_j: child segment rotation -> joint frame (H_post)
    joint_tributary: Array  # [J] m


def reference_geometry(structure: Structure, params: StructureParameters) -> ReferenceGeometry:
    """Reference frames (parallel transport along the tree), lengths and joint splits."""
    a = np.array([n[0] for n in structure.segment_nodes], dtype=np.int32)
    b = np.array([n[1] for n in structure.segment_nodes], dtype=np.int32)
    x = params.node_position
    chord = x[b] - x[a]
    length = jnp.linalg.norm(chord, axis=-1)
    tangent = chord / length[:, None]
    parents = structure.orientation_parent
    is_root = np.array([p == GROUND for p in parents])
    parent_index = np.array([max(p, 0) for p in parents], dtype=np.int32)
    # World rotation taking the parent's axis to this segment's axis (parallel transport).
    transport = minimal_rotation(tangent[parent_index], tangent)
    local = jnp.where(is_root[:, None, None], _tangent_frame(tangent), transport)
    frame = compose_along_tree(local, parents, lambda anc, own: matmul3(own, anc), jnp.eye(3))

    # Tree joints: the reference relative rotation Q_p0^T Q_s0 = H_pre H_post is split at the
    # joint frame (bisector for a bend, the child's frame for an attachment).
    kind = np.array(structure.joint_kind)
    parent_frame = frame[parent_index]
    relative = matmul3(transpose3(parent_frame), frame)
    axis_in_parent = matvec3(transpose3(parent_frame), tangent)
    bisector = axis_in_parent + _E3
    bisector = bisector / jnp.linalg.norm(bisector, axis=-1, keepdims=True)
    half = minimal_rotation(jnp.broadcast_to(_E3, bisector.shape), bisector)
    eye = jnp.broadcast_to(jnp.eye(3), relative.shape)
    bend = (kind == JOINT_BEND)[:, None, None]
    attach = (kind == JOINT_ATTACH)[:, None, None]
    pre = jnp.where(bend, half, jnp.where(attach, relative, eye))
    post = jnp.where(bend, half, eye)
    ground = is_root[:, None, None]
    parent_map = jnp.where(ground, 0.0, transpose3(pre))
    parent_length = length[parent_index]
    tributary = jnp.where(kind == JOINT_BEND, 0.5 * (length + parent_length), 0.5 * length)

    tree = np.array(structure.spring_joint_topology().spring_segments, np.int32)
    parent_map, child_map, tributary = parent_map[tree], post[tree], tributary[tree]
    if structure.derived_frames:
        # Derived joints (further clamps, loop closures): rotation log(D^T Q_a^T Q_b) with
        # the reference relative rotation D = Q_a0^T Q_b0 (identity against the ground).
        da = np.array([f[0] for f in structure.derived_frames], dtype=np.int32)
        db = np.array([f[1] for f in structure.derived_frames], dtype=np.int32)
        on_ground = (da == GROUND)[:, None, None]
        frame_a = jnp.where(on_ground, frame[db], frame[np.maximum(da, 0)])
        derived_reference = matmul3(transpose3(frame_a), frame[db])
        dkind = np.array(structure.derived_kind)
        derived_tributary = jnp.where(
            dkind == JOINT_BEND, 0.5 * (length[db] + length[np.maximum(da, 0)]), 0.5 * length[db]
        )
        parent_map = jnp.concatenate(
            [parent_map, jnp.where(on_ground, 0.0, transpose3(derived_reference))])
        child_map = jnp.concatenate(
            [child_map, jnp.broadcast_to(jnp.eye(3), (len(db), 3, 3))])
        tributary = jnp.concatenate([tributary, derived_tributary])

    sign = np.array(
        [1.0 if st == nodes[0] else -1.0
         for st, nodes in zip(structure.segment_start, structure.segment_nodes)]
    )
    end_vector = (sign * length)[:, None] * _E3
    return ReferenceGeometry(
        frame=frame, length=length, end_vector=end_vector, joint_parent_map=parent_map,
        joint_child_map=child_map, joint_tributary=tributary,
    )
