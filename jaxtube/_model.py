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
    """Drive ``node`` (global index) along unit ``direction [3]`` by ``displacements [K]`` [m]."""

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
            ``jaxtube._mechanics``).
        multipliers: ``[m]`` Lagrange multipliers (supports, loops, control).
        converged, iterations, result, residual: solver report (see RESULT_MESSAGES).
        node_position: deformed node positions ``[N, 3]`` [m].
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


def scale_loads(params: StructureParameters, factor) -> StructureParameters:
    """Parameters with point forces, torques and line loads multiplied by ``factor``."""
    return eqx.tree_at(
        lambda p: (p.node_force, p.node_torque, p.line_load),
        params,
        (params.node_force * factor, params.node_torque * factor, params.line_load * factor),
    )


def total_energy(structure: Structure, params, geometry: ReferenceGeometry, state) -> Array:
    """Total potential energy: joint strain energy plus the potential of the dead loads [J]."""
    config = configuration(structure, geometry, state)
    return _energy_of(structure, params, geometry, config, state)


def _energy_of(structure, params, geometry, config, state) -> Array:
    joints = spring_joints(structure, geometry, state)
    return (strain_energy(joints, params) + shear_energy(structure, geometry, params, state)
            + load_potential(structure, geometry, config, params, state))


def _constraints(structure, config, state, params, control) -> Array:
    c = support_constraints(structure, config, state, params)
    if control is not None:
        node, direction, value = control
        moved = config.node_position[node] - params.node_position[node]
        c = jnp.concatenate([c, (jnp.dot(moved, direction) - value)[None]])
    return c


def _objective(structure, geometry, state, params, control):
    """Energy [J] and constraints [m] from one evaluation of the kinematics."""
    terms, c = _objective_terms(structure, geometry, state, params, control)
    return jnp.sum(terms), c


def _objective_terms(structure, geometry, state, params, control):
    """Energy terms ``[3]`` (joint strain energy, shear energy, load potential) [J] and
    constraints [m]: the solver's stopping rule takes its force scale from each term's
    gradient (internal spring forces, applied loads) and from the reactions."""
    config = configuration(structure, geometry, state)
    joints = spring_joints(structure, geometry, state)
    terms = jnp.stack([strain_energy(joints, params),
                       shear_energy(structure, geometry, params, state),
                       load_potential(structure, geometry, config, params, state)])
    return terms, _constraints(structure, config, state, params, control)


def lagrangian_hessian(structure: Structure, geometry: ReferenceGeometry, params, control,
                       state: dict, multipliers: Array) -> Array:
    """Hessian of ``L = E + lambda . c`` w.r.t. the flattened state, ``[n, n]``: the blocks
    of :func:`lagrangian_hessian_blocks` scatter-added into a dense matrix."""
    blocks = lagrangian_hessian_blocks(structure, geometry, params, control, state,
                                       multipliers)
    n = sum(leaf.size for leaf in jax.tree_util.tree_leaves(state))
    rows = np.concatenate([r.reshape(-1) for r, _, _ in blocks])
    cols = np.concatenate([c.reshape(-1) for _, c, _ in blocks])
    values = jnp.concatenate([v.reshape(-1) for _, _, v in blocks])
    return jnp.zeros((n, n), values.dtype).at[rows, cols].add(values)


def lagrangian_hessian_blocks(structure: Structure, geometry: ReferenceGeometry, params,
                              control, state: dict, multipliers: Array) -> list:
    """Hessian of ``L = E + lambda . c`` w.r.t. the flattened state as a list of blocks
    ``(rows, cols, values)`` (static index arrays, element Hessians; the interface of
    ``jaxtube._kkt_linear``), from element Hessians (the exact Hessian, not an
    approximation).

    Node positions are ``root + sum_s Q_s0 exp(phi_s) e_s`` and every load potential and
    constraint is linear in the root position and the segment vectors ``step_s``, so with
    ``g_s = dL/dstep_s`` (one reverse pass) the position part contributes a 3 x 3 block
    ``d^2/dphi_s^2 [g_s . Q_s0 exp(phi_s) e_s]`` per segment (5 x 5 over ``(phi_s,
    gamma_s)`` with shear, whose energy is per segment too); each spring joint contributes a
    6 x 6 block over the rotations of its two segments; torques are linear in ``phi``. The
    blocks come from ``jax.hessian`` of these small element functions, vmapped, and are
    scatter-added at static indices. Cost grows linearly with the segment count (the
    dense autodiff Hessian grows quadratically and pushes every unknown through the chain).
    """
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

    leaves, treedef = jax.tree_util.tree_flatten(state)  # the order of ravel_pytree
    offsets = np.cumsum([0] + [leaf.size for leaf in leaves])
    index = treedef.unflatten([np.arange(o, o + leaf.size).reshape(leaf.shape)
                               for o, leaf in zip(offsets, leaves)])
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

    return list(zip(rows, cols, values))


def _post_process(structure, params, geometry, eq, control, factor) -> Solution:
    state = eq.state
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
        displacement = jnp.dot(config.node_position[node] - params.node_position[node], direction)
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
        node_position=config.node_position,
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
    geometry = reference_geometry(structure, params)
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
        return _objective_terms(structure, g, state, p,
                                None if c is None else (ctrl[0], c[0], c[1]))

    def hessian(state, multipliers, args):
        p, g, c = args
        return lagrangian_hessian_blocks(structure, g, p,
                                         None if c is None else (ctrl[0], c[0], c[1]),
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
    geometry = reference_geometry(structure, params)
    state0 = initial_state(structure, params)
    m_support = 3 * len(structure.supports) + 3 * len(structure.closures)

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
