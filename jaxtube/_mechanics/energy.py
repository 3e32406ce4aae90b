"""Energy of a structure and the constraints on it: joint springs, shear, dead loads, supports.

Joint ``j`` with rotation ``theta`` and tributary length ``l`` has curvature
``kappa = theta / l`` and energy ``l [W_bend(kappa_1^2 + kappa_2^2) + W_twist(kappa_3^2)]``
(docs/physics.md, sections 1.2 and 1.3); shear strains add ``S L |gamma|^2 / 2`` (section
2.4); loads are dead. :func:`energy_and_constraints` is the solver's objective: energy [J]
and constraints [m] from one evaluation of the kinematics.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jax import Array

from .._elements import (
    element_constraints,
    element_energy,
    element_load_potential,
    element_strain_energy,
)
from .._rotation import inverse_right_jacobian_transpose, matmul3, matvec3, transpose3
from .._structure.structure import Structure, StructureParameters
from .geometry import ReferenceGeometry, take_rows
from .kinematics import Configuration, JointSet, configuration, spring_joints
from .law_groups import law_groups


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


def strain_energy(joints: JointSet, params: StructureParameters) -> Array:
    """Sum over joints of ``l [W_bend(kappa_b^2) + W_twist(kappa_t^2)]`` [J]."""
    total = jnp.zeros(())
    radius_all = take_rows(params.node_radius, joints.node)
    for group in law_groups(joints.law_tube, params.bending_laws, params.torsion_laws):
        idx = group.joints
        length = take_rows(joints.tributary, idx)
        curvature = take_rows(joints.rotation, idx) / length[:, None]
        pressure = group.per_joint(params.pressure)
        radius = take_rows(radius_all, idx)
        bend_sq = curvature[:, 0] ** 2 + curvature[:, 1] ** 2
        twist_sq = curvature[:, 2] ** 2
        w = group.apply(group.law(params.bending_laws), "energy_density", bend_sq, pressure,
                        radius)
        w = w + group.apply(group.law(params.torsion_laws), "energy_density", twist_sq,
                            pressure, radius)
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
    for group in law_groups(joints.law_tube, params.bending_laws, params.torsion_laws):
        idx = group.joints
        curvature = joints.rotation[idx] / joints.tributary[idx][:, None]
        pressure, radius = group.per_joint(params.pressure), radius_all[idx]
        bend = jnp.sqrt(curvature[:, 0] ** 2 + curvature[:, 1] ** 2)
        safe = jnp.where(bend > 0, bend, 1.0)
        law_b, law_t = group.law(params.bending_laws), group.law(params.torsion_laws)
        # (the initial stiffness broadcast to the joints: a one-tube law gives a scalar)
        initial = jnp.broadcast_to(group.apply(law_b, "initial_stiffness", pressure,
                                               radius), bend.shape)
        scale = jnp.where(bend > 0, group.apply(law_b, "moment", bend, pressure, radius) / safe,
                          initial)
        m = jnp.concatenate(
            [scale[:, None] * curvature[:, :2],
             group.apply(law_t, "moment", curvature[:, 2], pressure, radius)[:, None]], axis=1,
        )
        moment = moment.at[idx].set(m)
        r = jnp.maximum(group.apply(law_b, "regime", bend, pressure, radius),
                        group.apply(law_t, "regime", curvature[:, 2], pressure, radius))
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


def total_energy(structure: Structure, params, geometry: ReferenceGeometry, state) -> Array:
    """Total potential energy: joint strain energy plus the potential of the dead loads,
    plus lines, pulleys and point masses [J]."""
    config = tube_configuration(structure, geometry, state)
    return potential_energy(structure, params, geometry, config, state)


def tube_configuration(structure, geometry, state) -> Configuration | None:
    """The tubes' configuration, or ``None`` for a structure without tubes."""
    return configuration(structure, geometry, state) if structure.segment_count else None


def potential_energy(structure, params, geometry, config, state) -> Array:
    energy = jnp.zeros(())
    if config is not None:
        joints = spring_joints(structure, geometry, state)
        energy = (strain_energy(joints, params) + shear_energy(structure, geometry, params, state)
                  + load_potential(structure, geometry, config, params, state))
    if structure.elements.active:
        energy = energy + element_energy(structure.elements, params.elements, params.gravity,
                                         state["point_position"])
    return energy


def node_displacement(structure, config, state, params, node: int) -> Array:
    """``x - X`` of a global node (tube node or point node) [m], ``[3]``."""
    if node < structure.node_count:
        return config.node_position[node] - params.node_position[node]
    row = node - structure.node_count
    return state["point_position"][row] - params.elements.point_position[row]


def constraints(structure, config, state, params, control) -> Array:
    parts = [jnp.zeros((0,))]
    if config is not None:
        parts.append(support_constraints(structure, config, state, params))
    if structure.elements.active:
        parts.append(element_constraints(structure.elements, params.elements,
                                         state["point_position"],
                                         None if config is None else config.node_position))
    if control is not None:
        node, direction, value = control
        moved = node_displacement(structure, config, state, params, node)
        parts.append((jnp.dot(moved, direction) - value)[None])
    return jnp.concatenate(parts)


def energy_and_constraints(structure, geometry, state, params, control):
    """Energy [J] and constraints [m] from one evaluation of the kinematics."""
    terms, c = energy_terms_and_constraints(structure, geometry, state, params, control)
    return jnp.sum(terms), c


def energy_terms_and_constraints(structure, geometry, state, params, control):
    """Energy terms ``[k]`` [J] and the constraints [m], from one evaluation of the
    kinematics. The terms are those the structure has, in this order: joint strain energy,
    shear energy (with shear), the tubes' load potential (with tubes), line and pulley
    strain energy, the point nodes' load potential (with point elements). The solver's
    stopping rule takes its force scale from each term's gradient (internal spring forces,
    applied loads) and from the reactions, never from the tangent stiffness; a term that is
    identically zero for the structure is left out (the solver would otherwise pull a zero
    cotangent back through the whole kinematics in every linearisation)."""
    config = tube_configuration(structure, geometry, state)
    terms = []
    if config is not None:
        joints = spring_joints(structure, geometry, state)
        terms.append(strain_energy(joints, params))
        if "segment_shear" in state:
            terms.append(shear_energy(structure, geometry, params, state))
        terms.append(load_potential(structure, geometry, config, params, state))
    if structure.elements.active:
        points = state["point_position"]
        terms.append(element_strain_energy(structure.elements, params.elements, points))
        terms.append(element_load_potential(structure.elements, params.elements,
                                            params.gravity, points))
    terms = jnp.stack([jnp.asarray(t, dtype=float) for t in terms]) if terms else jnp.zeros(1)
    return terms, constraints(structure, config, state, params, control)
