"""Kinematics and total potential energy of a rigid-segment tube structure.

State (a PyTree, so that new kinds of degrees of freedom can join later)::

    {"root_position": [3] m, "segment_rotation": [S, 3] rad}

``segment_rotation[s] = phi_s`` is the rotation of rigid segment ``s`` from its reference
orientation, in its material frame: ``Q_s = Q_s0 exp(phi_s)``. The joint rotation of a
spherical joint between segments ``a`` (parent) and ``b`` follows from the two, in the joint
frame (its third axis is the tube axis there, so its first two components are bending and
the third is torsion; Breukels & Ockels 2008)::

    exp(theta) = H_pre^T Q_a^T Q_b H_post^T = exp(-H_pre^T phi_a) exp(H_post phi_b)

where ``H_pre H_post = Q_a0^T Q_b0`` is the reference relative rotation. Between two segments
of one tube ``H_pre = H_post`` = half the reference bend (the joint frame bisects the two
axes, so an arc's bending and torsion are split symmetrically); where a tube is attached to
another, ``H_pre`` is the whole reference rotation and the joint frame is the attached tube's.

Why segment rotations rather than joint rotations as unknowns: node positions are then sums
of independent per-segment terms ``Q_s0 exp(phi_s) e_s``, so every load and every support
or control constraint is separable by segment, and each spring couples only its two
segments. The Hessian of the Lagrangian is block-sparse along the joints and is assembled
from small element Hessians (:func:`jaxtube._model` ``lagrangian_hessian``) instead of
pushing every unknown through the whole chain. The model (its energy and its equilibria) is
the same; only the coordinates differ.

Energy (per unit length laws, PHYSICS.md section 1): joint ``j`` with rotation ``theta`` and
tributary length ``l`` has curvature ``kappa = theta / l`` and energy
``l [W_bend(kappa_1^2 + kappa_2^2) + W_twist(kappa_3^2)]``, isotropic in the cross-section.
Loads are dead: point forces and torques, uniform line loads and self-weight (lumped at
segment midpoints, which is exact for a rigid segment).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._elements import initial_point_position
from ._rotation import (
    inverse_right_jacobian_transpose,
    matmul3,
    matvec3,
    minimal_rotation,
    rotation_matrix,
    rotation_vector,
    transpose3,
)
from ._structure import (
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


def spring_joint_topology(structure: Structure):
    """Static ``(parent segment or GROUND, child segment, node, law tube)`` per spring joint."""
    tree = [s for s, spring in enumerate(structure.joint_spring) if spring]
    parent = [structure.orientation_parent[s] for s in tree] + [a for a, _ in
                                                                 structure.derived_frames]
    child = tree + [b for _, b in structure.derived_frames]
    node = [structure.joint_node[s] for s in tree] + list(structure.derived_node)
    law = [structure.joint_law_tube[s] for s in tree] + list(structure.derived_law_tube)
    return (np.array(parent, np.int32), np.array(child, np.int32), tuple(node), tuple(law),
            np.array(tree, np.int32))


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

    _, _, _, _, tree = spring_joint_topology(structure)
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


def shear_stiffness(structure: Structure, params: StructureParameters) -> Array:
    """Fichter section shear stiffness of each segment ``S = p pi r^2 + r / u`` [N], ``[S]``
    (``r`` the segment's mean radius, ``u`` its tube's shear flexibility)."""
    a = np.array([n[0] for n in structure.segment_nodes], dtype=np.int32)
    b = np.array([n[1] for n in structure.segment_nodes], dtype=np.int32)
    tube = np.array(structure.segment_tube, dtype=np.int32)
    radius = 0.5 * (params.node_radius[a] + params.node_radius[b])
    return params.pressure[tube] * jnp.pi * radius**2 + radius / params.shear_flexibility[tube]


def shear_energy(structure: Structure, geometry: ReferenceGeometry, params, state) -> Array:
    """``sum_s S_s L_s |gamma_s|^2 / 2`` [J] (zero without shear)."""
    if "segment_shear" not in state:
        return jnp.zeros(())
    stiffness = shear_stiffness(structure, params)
    return 0.5 * jnp.sum(stiffness * geometry.length * jnp.sum(state["segment_shear"] ** 2, -1))


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
    parent, child, node, law, _ = spring_joint_topology(structure)
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


def law_groups(law_tube: tuple[int, ...]) -> dict[int, np.ndarray]:
    groups: dict[int, list[int]] = {}
    for j, t in enumerate(law_tube):
        groups.setdefault(t, []).append(j)
    return {t: np.array(js, dtype=np.int32) for t, js in groups.items()}


def strain_energy(joints: JointSet, params: StructureParameters) -> Array:
    """Sum over joints of ``l [W_bend(kappa_b^2) + W_twist(kappa_t^2)]`` [J]."""
    total = jnp.zeros(())
    radius_all = take_rows(params.node_radius, joints.node)
    for tube, idx in law_groups(joints.law_tube).items():
        length = take_rows(joints.tributary, idx)
        curvature = take_rows(joints.rotation, idx) / length[:, None]
        pressure = params.pressure[tube]
        radius = take_rows(radius_all, idx)
        bend_sq = curvature[:, 0] ** 2 + curvature[:, 1] ** 2
        twist_sq = curvature[:, 2] ** 2
        w = params.bending_laws[tube].energy_density(bend_sq, pressure, radius)
        w = w + params.torsion_laws[tube].energy_density(twist_sq, pressure, radius)
        total = total + jnp.sum(length * w)
    return total


def joint_moments(joints: JointSet, params: StructureParameters) -> tuple[Array, Array]:
    """Joint moment vectors in the joint frame [N m] and regimes (0/1/2), shapes ``[J, 3]``,
    ``[J]``. Bending moment ``M(|kappa_b|) kappa_b / |kappa_b|``; torsion ``M_t(kappa_3)``.
    The regime is the worse of the bending and torsion regimes."""
    count = joints.rotation.shape[0]
    moment = jnp.zeros((count, 3))
    regime = jnp.zeros((count,), dtype=jnp.int32)
    radius_all = params.node_radius[np.array(joints.node, dtype=np.int32)]
    for tube, idx in law_groups(joints.law_tube).items():
        curvature = joints.rotation[idx] / joints.tributary[idx][:, None]
        pressure, radius = params.pressure[tube], radius_all[idx]
        bend = jnp.sqrt(curvature[:, 0] ** 2 + curvature[:, 1] ** 2)
        safe = jnp.where(bend > 0, bend, 1.0)
        law_b, law_t = params.bending_laws[tube], params.torsion_laws[tube]
        scale = jnp.where(bend > 0, law_b.moment(bend, pressure, radius) / safe,
                          law_b.initial_stiffness(pressure, radius))
        m = jnp.concatenate(
            [scale[:, None] * curvature[:, :2],
             law_t.moment(curvature[:, 2], pressure, radius)[:, None]], axis=1,
        )
        moment = moment.at[idx].set(m)
        r = jnp.maximum(law_b.regime(bend, pressure, radius),
                        law_t.regime(curvature[:, 2], pressure, radius))
        regime = regime.at[idx].set(r.astype(jnp.int32))
    return moment, regime


def segment_loads(structure: Structure, geometry: ReferenceGeometry, params) -> Array:
    """Resultant distributed load on each segment (line load + self-weight), ``[S, 3]`` [N]."""
    tube = np.array(structure.segment_tube, dtype=np.int32)
    per_length = params.line_load[tube] + params.mass_per_length[tube][:, None] * params.gravity
    return per_length * geometry.length[:, None]


def load_potential(
    structure: Structure, geometry: ReferenceGeometry, config: Configuration, params,
    state: dict,
) -> Array:
    """Potential of the dead loads [J]: ``-sum F.x - sum q L . x_mid - sum T . psi``.

    Torques act on the segment ending at their node; ``psi = Q_s0 phi_s`` is that segment's
    world rotation vector from the reference (a conservative axial-vector torque, exact for
    a fixed axis).
    """
    potential = -jnp.sum(params.node_force * config.node_position)
    midpoint = 0.5 * (config.segment_start + config.segment_end)
    potential = potential - jnp.sum(segment_loads(structure, geometry, params) * midpoint)
    if structure.torque_nodes:
        seg = np.array([structure.node_segment[n] for n in structure.torque_nodes], np.int32)
        psi = matvec3(take_rows(geometry.frame, seg), take_rows(state["segment_rotation"], seg))
        potential = potential - jnp.sum(params.node_torque * psi)
    return potential


def support_constraints(structure: Structure, config: Configuration, state: dict, params) -> Array:
    """Equality constraints [m]: the root and every other support stay at their reference
    positions; every closed loop closes. Their multipliers are minus the reaction forces.
    Without supports the root floats (no constraint)."""
    parts = [jnp.zeros((0,), state["root_position"].dtype)]
    if structure.supports:
        parts.append(state["root_position"] - params.node_position[structure.root_node])
    for node, _kind in structure.supports[1:]:
        parts.append(config.node_position[node] - params.node_position[node])
    for segment, node in structure.closures:
        parts.append(config.segment_end[segment] - config.node_position[node])
    return jnp.concatenate(parts)


def world_joint_moments(config: Configuration, joints: JointSet, moment: Array) -> Array:
    """Physical joint moments in the world frame, ``[J, 3]`` [N m].

    ``moment`` is the law's ``dW/dtheta``. The moment transmitted through a finite rotation
    is ``J_r(theta)^{-T} dW/dtheta`` in the frame after ``exp(theta)``, which is
    ``Q_s H_post^T`` (``Q_s = Q_parent H_pre exp(theta) H_post``). The difference is second
    order in the joint rotation, but it makes support moments balance exactly.
    """
    seg = np.array(joints.frame_segment, dtype=np.int32)
    joint_frame = matmul3(take_rows(config.frame, seg), transpose3(joints.post))
    physical = matvec3(inverse_right_jacobian_transpose(joints.rotation), moment)
    return matvec3(joint_frame, physical)

