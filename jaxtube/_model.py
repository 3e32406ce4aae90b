"""Equilibrium of a structure at one load level, and load paths by stepping inside ``jit``.

Controls:

- :class:`ForceControl`: the point forces, torques and line loads of the parameters are
  scaled by each load factor; self-weight stays on (gravity is not a test load).
- :class:`DisplacementControl`: one node is driven along a unit direction
  (``(x - X) . d = u``); the force the actuator applies along ``d`` is the constraint's
  reaction. This traces softening and the collapse plateau, where force control fails.

The path is a ``lax.scan`` over steps, each warm-started from the previous one; every step's
solution carries its own convergence flag. Gradients w.r.t. the parameters come by the
implicit function theorem at every step.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._elements import (
    dense_from_blocks,
    element_constraints,
    element_energy,
    element_hessian_blocks,
    element_results,
    state_index,
)
from ._mechanics import (
    Configuration,
    ReferenceGeometry,
    configuration,
    initial_state,
    joint_moments,
    law_groups,
    load_potential,
    positions_from_steps,
    reference_geometry,
    relative_joint_rotation,
    segment_steps,
    shear_energy,
    shear_stiffness,
    spring_joint_topology,
    spring_joints,
    strain_energy,
    support_constraints,
    world_joint_moments,
)
from ._rotation import matvec3, rotation_matrix, transpose3
from ._solver import RESULT_MESSAGES, NewtonKKT, solve_equilibrium
from ._structure import GROUND, JOINT_GROUND, Structure, StructureParameters


class ForceControl(eqx.Module):
    """Load factors ``[K]`` applied to the point forces, torques and line loads."""

    load_factors: Array

    def __init__(self, load_factors):
        self.load_factors = jnp.asarray(load_factors, dtype=float)


class DisplacementControl(eqx.Module):
    """Drive ``node`` (global index: a tube node or a point node) along unit
    ``direction [3]`` by ``displacements [K]`` [m]."""

    node: int = eqx.field(static=True)
    direction: Array
    displacements: Array

    def __init__(self, node: int, direction, displacements):
        self.node = int(node)
        direction = jnp.asarray(direction, dtype=float)
        self.direction = direction / jnp.linalg.norm(direction)
        self.displacements = jnp.asarray(displacements, dtype=float)


class Solution(eqx.Module):
    """Equilibrium of a structure (one load level; under a path every leaf gains a leading
    ``[K]`` step axis).

    Attributes:
        state: ``{"root_position": [3], "segment_rotation": [S, 3]}`` (see
            ``jaxtube._mechanics``), with ``"point_position": [P, 3]`` when the structure
            has point nodes, lines or pulleys.
        multipliers: ``[m]`` Lagrange multipliers (supports, loops, fixed points and
            attachment ties, control).
        converged, iterations, result, residual: solver report (see RESULT_MESSAGES).
        node_position: deformed positions of every node ``[N + P0, 3]`` [m]: tube nodes,
            then the structure's point nodes (``Structure.node_id`` numbering).
        joint_rotation: rotation vectors of the spring joints ``[J, 3]`` [rad].
        joint_curvature: ``[J, 3]`` [1/m] (bending 1, bending 2, twist).
        joint_moment: joint frame ``[J, 3]`` [N m]; joint_moment_world: world frame.
        joint_regime: ``[J]`` 0 unwrinkled, 1 wrinkled, 2 collapsed.
        reaction_force: force each support exerts on the structure ``[n_supports, 3]`` [N].
        reaction_moment: moment each support exerts on the structure ``[n_supports, 3]``
            [N m] (clamps; zero for pins).
        control_force: force applied by the displacement actuator along its direction [N]
            (under force control: the applied force at that node along it, or 0).
        control_displacement: ``(x - X) . d`` at the controlled node [m].
        load_factor: the force-control factor (1 under displacement control).
        point_position: the point nodes ``[P0, 3]`` [m] (free and fixed, declaration order).
        line_length, line_tension, line_taut: per line ``[L]``: m, N (``k (l - L0)`` when
            taut, smoothed over the tension smoothing), carries tension.
        pulley_length, pulley_tension, pulley_taut: per pulley rope ``[Q]`` (one tension
            on both sides).
        fixed_point_reaction: force each fixed point exerts on the structure ``[F, 3]`` [N].
        attachment_force: force the lines, pulleys and masses apply to each attached tube
            node ``[A, 3]`` [N] (``Structure.elements.attachment_nodes``).
    """

    state: dict
    multipliers: Array
    converged: Array
    iterations: Array
    result: Array
    residual: Array
    node_position: Array
    joint_rotation: Array
    joint_curvature: Array
    joint_moment: Array
    joint_moment_world: Array
    joint_regime: Array
    reaction_force: Array
    reaction_moment: Array
    control_force: Array
    control_displacement: Array
    load_factor: Array
    point_position: Array
    line_length: Array
    line_tension: Array
    line_taut: Array
    pulley_length: Array
    pulley_tension: Array
    pulley_taut: Array
    fixed_point_reaction: Array
    attachment_force: Array


def scale_loads(params: StructureParameters, factor) -> StructureParameters:
    """Parameters with point forces (on tube and point nodes), torques and line loads
    multiplied by ``factor``."""
    return eqx.tree_at(
        lambda p: (p.node_force, p.node_torque, p.line_load, p.elements.point_force),
        params,
        (params.node_force * factor, params.node_torque * factor, params.line_load * factor,
         params.elements.point_force * factor),
    )


def total_energy(structure: Structure, params, geometry: ReferenceGeometry, state) -> Array:
    """Total potential energy: joint strain energy plus the potential of the dead loads,
    plus lines, pulleys and point masses [J]."""
    config = _configuration(structure, geometry, state)
    return _energy_of(structure, params, geometry, config, state)


def _configuration(structure, geometry, state) -> Configuration | None:
    """The tubes' configuration, or ``None`` for a structure without tubes."""
    return configuration(structure, geometry, state) if structure.segment_count else None


def _energy_of(structure, params, geometry, config, state) -> Array:
    energy = jnp.zeros(())
    if config is not None:
        joints = spring_joints(structure, geometry, state)
        energy = (strain_energy(joints, params) + shear_energy(structure, geometry, params, state)
                  + load_potential(structure, geometry, config, params, state))
    if structure.elements.active:
        energy = energy + element_energy(structure.elements, params.elements, params.gravity,
                                         state["point_position"])
    return energy


def _node_displacement(structure, config, state, params, node: int) -> Array:
    """``x - X`` of a global node (tube node or point node) [m], ``[3]``."""
    if node < structure.node_count:
        return config.node_position[node] - params.node_position[node]
    row = node - structure.node_count
    return state["point_position"][row] - params.elements.point_position[row]


def _constraints(structure, config, state, params, control) -> Array:
    parts = [jnp.zeros((0,))]
    if config is not None:
        parts.append(support_constraints(structure, config, state, params))
    if structure.elements.active:
        parts.append(element_constraints(structure.elements, params.elements,
                                         state["point_position"],
                                         None if config is None else config.node_position))
    if control is not None:
        node, direction, value = control
        moved = _node_displacement(structure, config, state, params, node)
        parts.append((jnp.dot(moved, direction) - value)[None])
    return jnp.concatenate(parts)


def _objective(structure, geometry, state, params, control):
    """Energy [J] and constraints [m] from one evaluation of the kinematics."""
    config = _configuration(structure, geometry, state)
    energy = _energy_of(structure, params, geometry, config, state)
    return energy, _constraints(structure, config, state, params, control)


def lagrangian_hessian(structure: Structure, geometry: ReferenceGeometry, params, control,
                       state: dict, multipliers: Array) -> Array:
    """Hessian of ``L = E + lambda . c`` w.r.t. the flattened state, ``[n, n]``, assembled
    from element Hessians (the exact Hessian, not an approximation).

    Node positions are ``root + sum_s Q_s0 exp(phi_s) e_s`` and every load potential and
    constraint is linear in the root position and the segment vectors ``step_s``, so with
    ``g_s = dL/dstep_s`` (one reverse pass) the position part contributes a 3 x 3 block
    ``d^2/dphi_s^2 [g_s . Q_s0 exp(phi_s) e_s]`` per segment (5 x 5 over ``(phi_s,
    gamma_s)`` with shear, whose energy is per segment too); each spring joint contributes a
    6 x 6 block over the rotations of its two segments; torques are linear in ``phi``. The
    blocks come from ``jax.hessian`` of these small element functions, vmapped, and are
    scatter-added at static indices. Cost grows linearly with the segment count (the
    dense autodiff Hessian grows quadratically and pushes every unknown through the chain).
    Lines and pulleys add 6 x 6 and 9 x 9 blocks over their point nodes
    (``jaxtube._elements.element_hessian_blocks``); attachment ties are linear in the
    segment vectors and enter through ``g_s``.
    """
    if not structure.segment_count:
        return dense_from_blocks(state, _element_blocks(structure, params, state))
    phi = state["segment_rotation"]
    frame, step = segment_steps(geometry, state)

    def linear_part(step):
        start, end, nodes = positions_from_steps(structure, state["root_position"], step)
        config = Configuration(frame=frame, segment_start=start, segment_end=end,
                               node_position=nodes)
        potential = load_potential(structure, geometry, config, params, state)
        return potential + jnp.dot(multipliers,
                                   _constraints(structure, config, state, params, control))

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

    parent, child, nodes, law, _ = spring_joint_topology(structure)
    for tube, idx in law_groups(law).items():
        bending, torsion = params.bending_laws[tube], params.torsion_laws[tube]
        pressure = params.pressure[tube]

        def joint_energy(pair, parent_map, child_map, grounded, tributary, radius):
            theta = relative_joint_rotation(pair[:3], pair[3:], parent_map, child_map, grounded)
            kappa = theta / tributary
            w = bending.energy_density(kappa[0] ** 2 + kappa[1] ** 2, pressure, radius)
            return tributary * (w + torsion.energy_density(kappa[2] ** 2, pressure, radius))

        a, b = np.maximum(parent[idx], 0), child[idx]
        pair = jnp.concatenate([phi[a], phi[b]], axis=1)
        radius = params.node_radius[np.array([nodes[j] for j in idx], dtype=np.int32)]
        blocks = jax.vmap(jax.hessian(joint_energy))(
            pair, geometry.joint_parent_map[idx], geometry.joint_child_map[idx],
            parent[idx] == -1, geometry.joint_tributary[idx], radius)
        pair_index = np.concatenate([rotation_index[a], rotation_index[b]], axis=1)  # [Jg, 6]
        rows.append(np.broadcast_to(pair_index[:, :, None], blocks.shape))
        cols.append(np.broadcast_to(pair_index[:, None, :], blocks.shape))
        values.append(blocks)

    blocks = list(zip(rows, cols, values)) + _element_blocks(structure, params, state)
    return dense_from_blocks(state, blocks)


def _element_blocks(structure, params, state) -> list:
    """Hessian blocks ``(rows, cols, values)`` of the lines and pulleys."""
    if not structure.elements.active:
        return []
    return element_hessian_blocks(structure.elements, params.elements,
                                  state["point_position"], state_index(state)["point_position"])


def _post_process(structure, params, geometry, eq, control, factor) -> Solution:
    state = eq.state
    if not structure.segment_count:
        return _points_only_solution(structure, params, eq, control, factor)
    config = configuration(structure, geometry, state)
    joints = spring_joints(structure, geometry, state)
    moment, regime = joint_moments(joints, params)
    n_support = len(structure.supports)
    reactions = -jnp.reshape(eq.multipliers[: 3 * n_support], (n_support, 3))
    world_moment = world_joint_moments(config, joints, moment)
    # A clamp joint's spring moment m acts on its segment as -m (the ground side is fixed).
    clamp_of_support = np.zeros((n_support, world_moment.shape[0]))
    support_index = {node: k for k, (node, _) in enumerate(structure.supports)}
    tree = [s for s, spring in enumerate(structure.joint_spring) if spring]
    kinds = [structure.joint_kind[s] for s in tree] + list(structure.derived_kind)
    grounded = [structure.orientation_parent[s] == GROUND for s in tree] + [
        a == GROUND for a, _ in structure.derived_frames]
    for j, (node, kind, ground) in enumerate(zip(joints.node, kinds, grounded)):
        if ground and kind == JOINT_GROUND and node in support_index:
            clamp_of_support[support_index[node], j] = -1.0
    reaction_moment = jnp.asarray(clamp_of_support) @ world_moment
    if control is not None:
        node, direction, _ = control
        control_force = -eq.multipliers[-1]
        displacement = jnp.dot(_node_displacement(structure, config, state, params, node),
                               direction)
    else:
        control_force = jnp.zeros(())
        displacement = jnp.zeros(())
    return Solution(
        state=state,
        multipliers=eq.multipliers,
        converged=eq.converged,
        iterations=eq.iterations,
        result=eq.result,
        residual=eq.residual,
        **element_results(structure, params, state, eq.multipliers,
                           None if config is None else config.node_position),
        joint_rotation=joints.rotation,
        joint_curvature=joints.rotation / joints.tributary[:, None],
        joint_moment=moment,
        joint_moment_world=world_moment,
        joint_regime=regime,
        reaction_force=reactions,
        reaction_moment=reaction_moment,
        control_force=control_force,
        control_displacement=displacement,
        load_factor=jnp.asarray(factor, dtype=float),
    )


def _points_only_solution(structure, params, eq, control, factor) -> Solution:
    """Solution of a structure without tubes: no joints, no supports."""
    if control is not None:
        node, direction, _ = control
        control_force = -eq.multipliers[-1]
        displacement = jnp.dot(_node_displacement(structure, None, eq.state, params, node),
                               direction)
    else:
        control_force, displacement = jnp.zeros(()), jnp.zeros(())
    none3, none = jnp.zeros((0, 3)), jnp.zeros((0,), jnp.int32)
    return Solution(
        state=eq.state, multipliers=eq.multipliers, converged=eq.converged,
        iterations=eq.iterations, result=eq.result, residual=eq.residual,
        **element_results(structure, params, eq.state, eq.multipliers, None),
        joint_rotation=none3, joint_curvature=none3, joint_moment=none3,
        joint_moment_world=none3, joint_regime=none, reaction_force=none3,
        reaction_moment=none3, control_force=control_force, control_displacement=displacement,
        load_factor=jnp.asarray(factor, dtype=float),
    )


def _reference_geometry(structure, params) -> ReferenceGeometry | None:
    return reference_geometry(structure, params) if structure.segment_count else None


def _constraint_count(structure) -> int:
    """Equality constraints before the control: supports, loops, fixed points, ties."""
    return (3 * len(structure.supports) + 3 * len(structure.closures)
            + structure.elements.constraint_count)


def equilibrium(
    structure: Structure,
    params: StructureParameters,
    control: DisplacementControl | None = None,
    displacement=None,
    initial=None,
    solver: NewtonKKT = NewtonKKT(),
) -> Solution:
    """Solve one equilibrium.

    Without ``control`` the loads in ``params`` act as given. With a
    :class:`DisplacementControl`, ``displacement`` [m] is imposed (default: its last value).
    ``initial`` is a previous :class:`Solution` to warm-start from.
    """
    geometry = _reference_geometry(structure, params)
    ctrl = None
    if control is not None:
        value = control.displacements[-1] if displacement is None else displacement
        ctrl = (control.node, control.direction, jnp.asarray(value, dtype=float))
    state0 = initial_state(structure, params) if initial is None else initial.state
    lam0 = None if initial is None else initial.multipliers
    return _solve(structure, params, geometry, ctrl, state0, lam0, solver, 1.0)


def _solve(structure, params, geometry, ctrl, state0, lam0, solver, factor) -> Solution:
    def objective(state, args):
        p, g, c = args
        return _objective(structure, g, state, p, None if c is None else (ctrl[0], c[0], c[1]))

    def hessian(state, multipliers, args):
        p, g, c = args
        return lagrangian_hessian(structure, g, p, None if c is None else (ctrl[0], c[0], c[1]),
                                  state, multipliers)

    c_args = None if ctrl is None else (ctrl[1], ctrl[2])
    eq = solve_equilibrium(objective, state0, (params, geometry, c_args), solver, lam0,
                           hessian=hessian)
    return _post_process(structure, params, geometry, eq, ctrl, factor)


def solve_path(
    structure: Structure,
    params: StructureParameters,
    path: ForceControl | DisplacementControl,
    solver: NewtonKKT = NewtonKKT(),
) -> Solution:
    """Follow a load path by stepping (``lax.scan``); returns a :class:`Solution` whose
    leaves have a leading step axis ``[K]``. Each step is warm-started from the previous
    one and reports its own convergence."""
    geometry = _reference_geometry(structure, params)
    state0 = initial_state(structure, params)
    m_support = _constraint_count(structure)

    if isinstance(path, DisplacementControl):
        lam0 = jnp.zeros((m_support + 1,))

        def step(carry, value):
            state, lam = carry
            ctrl = (path.node, path.direction, value)
            sol = _solve(structure, params, geometry, ctrl, state, lam, solver, 1.0)
            return (sol.state, sol.multipliers), sol

        _, sols = jax.lax.scan(step, (state0, lam0), path.displacements)
        return sols

    lam0 = jnp.zeros((m_support,))

    def step(carry, factor):
        state, lam = carry
        scaled = scale_loads(params, factor)
        sol = _solve(structure, scaled, geometry, None, state, lam, solver, factor)
        return (sol.state, sol.multipliers), sol

    _, sols = jax.lax.scan(step, (state0, lam0), path.load_factors)
    return sols


def check_converged(solution: Solution, what: str = "solve") -> None:
    """Raise ``RuntimeError`` naming every step that did not converge (host-side helper)."""
    converged = np.atleast_1d(np.asarray(solution.converged))
    if converged.all():
        return
    codes = np.atleast_1d(np.asarray(solution.result))
    residual = np.atleast_1d(np.asarray(solution.residual))
    bad = np.flatnonzero(~converged)
    lines = [
        f"step {k}: {RESULT_MESSAGES.get(int(codes[k]), 'unknown')} "
        f"(KKT residual {residual[k]:.3g})"
        for k in bad[:10]
    ]
    more = f" and {len(bad) - 10} more" if len(bad) > 10 else ""
    raise RuntimeError(f"{what}: {len(bad)} of {converged.size} steps did not converge:\n  "
                       + "\n  ".join(lines) + more)
