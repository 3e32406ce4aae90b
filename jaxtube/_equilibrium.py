"""Equilibrium of a structure at one load level: :func:`equilibrium` and its :class:`Solution`.

The state that minimises the total potential energy subject to the supports (and a
displacement control) is found by the Newton-KKT solver (:mod:`jaxtube._solver`);
:func:`solve_load_level` then reports the deformed shape, joint curvatures, moments and
regimes, the support reactions and the control force. Gradients w.r.t. the parameters come
by the implicit function theorem. :func:`check_converged` turns failed steps into words.
"""

from __future__ import annotations

from functools import partial

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._controls import DisplacementControl
from ._elements import element_results
from ._mechanics.constraint_factors import constraint_factors
from ._mechanics.constraint_pattern import constraint_jacobian_pattern
from ._mechanics.energy import (
    energy_terms_and_constraints,
    joint_moments,
    node_displacement,
    world_joint_moments,
)
from ._mechanics.geometry import ReferenceGeometry, reference_geometry
from ._mechanics.hessian import lagrangian_hessian_blocks
from ._mechanics.kinematics import configuration, initial_state, spring_joints
from ._solver.newton_kkt import RESULT_MESSAGES, NewtonKKT, solve_equilibrium
from ._structure.structure import GROUND, JOINT_GROUND, Structure, StructureParameters
from ._traced_once import jit_keeping_static_outputs


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
    topology = structure.spring_joint_topology()
    grounded = topology.parent_segment == GROUND
    for j, (node, kind, ground) in enumerate(zip(joints.node, topology.kind, grounded)):
        if ground and kind == JOINT_GROUND and node in support_index:
            clamp_of_support[support_index[node], j] = -1.0
    reaction_moment = jnp.asarray(clamp_of_support) @ world_moment
    if control is not None:
        node, direction, _ = control
        control_force = -eq.multipliers[-1]
        displacement = jnp.dot(node_displacement(structure, config, state, params, node),
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
        **element_results(structure, params, state, eq.multipliers, config.node_position),
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
        displacement = jnp.dot(node_displacement(structure, None, eq.state, params, node),
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


def tube_reference_geometry(structure, params) -> ReferenceGeometry | None:
    """The tubes' reference geometry, or ``None`` for a structure without tubes."""
    return reference_geometry(structure, params) if structure.segment_count else None


def constraint_count(structure) -> int:
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
    geometry = tube_reference_geometry(structure, params)
    ctrl = None
    if control is not None:
        value = control.displacements[-1] if displacement is None else displacement
        ctrl = (control.node, control.direction, jnp.asarray(value, dtype=float))
    state0 = initial_state(structure, params) if initial is None else initial.state
    lam0 = None if initial is None else initial.multipliers
    return solve_load_level(structure, params, geometry, ctrl, state0, lam0, solver, 1.0)


def solve_load_level(structure, params, geometry, ctrl, state0, lam0, solver, factor) -> Solution:
    """One equilibrium from ``state0`` (multipliers ``lam0`` or ``None``), reported as a
    :class:`Solution`. ``ctrl`` is ``None`` or ``(node, direction [3], displacement [m])``;
    ``factor`` is the load factor to report (the loads in ``params`` are already scaled)."""
    node = None if ctrl is None else ctrl[0]
    objective, hessian, factors = (partial(model, structure=structure, control_node=node)
                                   for model in (_objective, _hessian, _factors))
    c_args = None if ctrl is None else (ctrl[1], ctrl[2])
    pattern = constraint_jacobian_pattern(structure, state0, node)
    eq = solve_equilibrium(objective, state0, (params, geometry, c_args), solver, lam0,
                           hessian=hessian, constraint_pattern=pattern,
                           constraint_factors=factors if structure.segment_count else None)
    return _post_process(structure, params, geometry, eq, ctrl, factor)


# The model as the solver sees it, ``args = (params, geometry, (direction, displacement) or
# None)``: each traced once per structure, control node and shape (``jaxtube._traced_once``).


def _control(args, node):
    """``None`` or ``(node, direction [3], displacement [m])`` from the solver's args."""
    c = args[2]
    return None if c is None else (node, c[0], c[1])


def _model_objective(state, args, *, structure, control_node):
    return energy_terms_and_constraints(structure, args[1], state, args[0],
                                        _control(args, control_node))


def _model_hessian(state, multipliers, args, *, structure, control_node):
    return lagrangian_hessian_blocks(structure, args[1], args[0],
                                     _control(args, control_node), state, multipliers)


def _model_factors(state, args, *, structure, control_node):
    return constraint_factors(structure, args[1], args[0], _control(args, control_node),
                              state)


_STATIC = ("structure", "control_node")
_objective = jit_keeping_static_outputs(_model_objective, _STATIC)
_hessian = jit_keeping_static_outputs(_model_hessian, _STATIC)
_factors = jit_keeping_static_outputs(_model_factors, _STATIC)


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
