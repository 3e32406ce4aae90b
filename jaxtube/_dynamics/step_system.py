"""Each implicit step's linear algebra: the state extended by the segment centroids, the
incremental potential's Hessian assembled block by block, and the constraint Jacobian in the
factored form of the static solver's augmented sparse route.

**Why the centroids.** With segment rotations as unknowns a segment's centroid is a sum over
every segment on its path from the root, so the translational inertia
``|x(z) - x~|^2_M`` has a Hessian dense along those paths (``G^T A^T M A G``, ``A`` the
path sums): a dense ``[n, n]`` matrix per Newton iteration, and a dense factorisation. Keeping
the centroids ``u`` ``[S, 3]`` as unknowns, tied to the kinematics by the constraints

    u_s - (start_s(z) + end_s(z)) / 2 = 0,

makes the inertia block-diagonal (a 3 x 3 mass per segment on ``u``; a 3 x 3 rotational block
per segment on ``phi_s``; the point masses on the points), and the ties are affine in the
segment ends, so they join the structure's constraints in the factored form ``C_z + C_w G^{-1}
F`` of :mod:`jaxtube._solver.kkt_augmented` (every row local: no fill along tree paths). The
ties' curvature, ``-lambda_u . x(step(phi))``, is linear in the segment vectors and adds a
3 x 3 block per segment (the static Hessian's ``g_s`` term, :mod:`jaxtube._mechanics.hessian`).
Eliminating ``u`` gives back the step of the plain coordinates exactly (the same minimiser:
the ties hold at every solution).

The same system, without curvature, gives the rates of the constrained motion closest to a
target (:func:`constrained_rates`): the velocity projection after each step and the
consistent acceleration at rest.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.flatten_util import ravel_pytree

from .._elements import state_index
from .._mechanics.constraint_factors import _segment_dofs, _segment_step, constraint_factors
from .._mechanics.energy import energy_terms_and_constraints
from .._mechanics.hessian import lagrangian_hessian_blocks
from .._mechanics.kinematics import positions_from_steps, relative_joint_rotation, segment_steps
from .._rotation import right_jacobian, rotation_matrix, rotation_vector, transpose3
from .._solver.kkt_augmented import ConstraintFactors

# The step's own KKT system, solved once (a quadratic problem needs no Newton loop): the
# route and matrix of the solver's implicit tangent.
from .._solver.kkt_route import kkt_route
from .._solver.newton_kkt import NewtonKKT, _kkt_at_solution
from .._structure.structure import GROUND, Structure

#: The extended state's key of the segment centroids ``[S, 3]`` [m].
CENTROID = "segment_centroid"


def segment_centroids(structure: Structure, geometry, state: dict) -> Array:
    """The segments' midpoints ``[S, 3]`` [m] from the kinematics of ``state``."""
    _, step = segment_steps(geometry, state)
    start, end, _ = positions_from_steps(structure, state["root_position"], step)
    return 0.5 * (start + end)


def extended_state(structure: Structure, geometry, state: dict) -> dict:
    """``state`` with the segment centroids ``[S, 3]`` [m] added (unchanged without tubes)."""
    if not structure.segment_count:
        return state
    return dict(state, **{CENTROID: segment_centroids(structure, geometry, state)})


def structure_state(state: dict) -> dict:
    """The structure's own state from an extended one."""
    return {key: value for key, value in state.items() if key != CENTROID}


def centroid_ties(structure: Structure, geometry, state: dict) -> Array:
    """``u_s - (start_s + end_s) / 2`` ``[3 S]`` [m]."""
    if not structure.segment_count:
        return jnp.zeros((0,))
    return (state[CENTROID] - segment_centroids(structure, geometry, state)).reshape(-1)


def constraints_and_energy(structure: Structure, geometry, state: dict, params):
    """The structure's energy terms ``[k]`` [J] and its constraints followed by the centroid
    ties ``[m + 3 S]``, at an extended state."""
    terms, c = energy_terms_and_constraints(structure, geometry, state, params, None)
    return terms, jnp.concatenate([c, centroid_ties(structure, geometry, state)])


def step_factors(structure: Structure, geometry, params, state: dict) -> ConstraintFactors:
    """The constraints and centroid ties of an extended state in factored form
    (:class:`jaxtube._solver.kkt_augmented.ConstraintFactors`): the structure's factors
    (:func:`jaxtube._mechanics.constraint_factors.constraint_factors`) with three rows per
    segment appended, ``+1`` on ``u_s`` and ``-1/2`` on the segment's start and end."""
    factors = constraint_factors(structure, geometry, params, None, state)
    index = state_index(state)
    n = sum(int(np.size(v)) for v in jax.tree_util.tree_leaves(index))
    count = structure.segment_count
    m = jax.eval_shape(lambda s: energy_terms_and_constraints(structure, geometry, s, params,
                                                              None)[1], state).shape[0]
    ends = n + np.arange(3 * count).reshape(count, 3)
    parent = np.asarray(structure.position_parent)
    root = np.asarray(index["root_position"]).reshape(-1)
    starts = np.where((parent == GROUND)[:, None], root[None, :], ends[np.maximum(parent, 0)])
    rows = m + np.arange(3 * count).reshape(count, 3)
    half = jnp.full((count, 3), -0.5)
    ties = [(rows, np.asarray(index[CENTROID]), jnp.ones((count, 3))),
            (rows, ends, half), (rows, starts, half)]
    return ConstraintFactors(factors.aux_count, factors.tree, factors.constraint + ties)


def _tie_curvature_blocks(structure: Structure, geometry, state: dict, tie_multipliers):
    """Hessian blocks of ``-lambda_u . (start + end) / 2`` over each segment's unknowns: the
    ties are linear in the segment vectors, so with ``g_s`` their gradient with respect to
    ``step_s`` each segment adds ``d^2/d(dofs_s)^2 [g_s . step_s(dofs_s)]``."""
    _, step = segment_steps(geometry, state)
    lam = tie_multipliers.reshape(-1, 3)

    def tie_work(step):
        start, end, _ = positions_from_steps(structure, state["root_position"], step)
        return -0.5 * jnp.sum(lam * (start + end))

    step_force = jax.grad(tie_work)(step)
    blocks = jax.vmap(jax.hessian(lambda d, g, q, e, length: g @ _segment_step(d, q, e, length)))(
        _segment_dofs(state), step_force, geometry.frame, geometry.end_vector, geometry.length)
    index = state_index(state)
    dofs = [np.asarray(index["segment_rotation"])]
    if "segment_shear" in state:
        dofs.append(np.asarray(index["segment_shear"]))
    dofs = np.concatenate(dofs, axis=1)
    return _block(dofs, dofs, blocks)


def _block(row_index, col_index, values):
    """A block ``(rows, cols, values)`` of per-item matrices ``values [B, r, c]``."""
    return (np.broadcast_to(row_index[:, :, None], values.shape),
            np.broadcast_to(col_index[:, None, :], values.shape), values)


def rotational_potential(phi, frame0, frame_then, predicted, rate, inertia, weight, damping):
    """One segment's rotational part of the incremental potential [J] (``.integrator``):
    ``weight dpsi . J dpsi + damping rate . J dpsi``, ``dpsi = log(Q_n^T Q_0 exp(phi)) -
    Psi~``. Shapes: ``phi [3]``, frames ``[3, 3]``, ``predicted``, ``rate``, ``inertia [3]``."""
    psi = rotation_vector(transpose3(frame_then) @ (frame0 @ rotation_matrix(phi)))
    dpsi = psi - predicted
    return weight * jnp.sum(inertia * dpsi * dpsi) + damping * jnp.sum(rate * inertia * dpsi)


def joint_damping_potential(pair, parent_map, child_map, grounded, then, rate, coefficient,
                            step):
    """One joint's damping part of the incremental potential [J]: ``sum c (dtheta^2 / h -
    thetadot_n dtheta)``, ``dtheta = theta(phi_a, phi_b) - theta_n`` (``pair [6]``)."""
    theta = relative_joint_rotation(pair[:3], pair[3:], parent_map, child_map, grounded)
    dtheta = theta - then
    return jnp.sum(coefficient * (dtheta * dtheta / step - rate * dtheta))


def step_hessian_blocks(structure: Structure, geometry, params, state: dict, multipliers,
                        data) -> list:
    """The exact Hessian of the step's Lagrangian (incremental potential plus multipliers
    times constraints and ties) over the extended state, as blocks ``(rows, cols, values)``:
    the static Lagrangian's (:func:`jaxtube._mechanics.hessian.lagrangian_hessian_blocks`)
    and :func:`inertial_hessian_blocks`. ``data``: the step's ``_StepData``
    (:mod:`.integrator`)."""
    structural = multipliers[: multipliers.shape[0] - 3 * structure.segment_count]
    return (lagrangian_hessian_blocks(structure, geometry, params, None, state, structural)
            + inertial_hessian_blocks(structure, geometry, state,
                                      multipliers[structural.shape[0]:], data))


def inertial_hessian_blocks(structure: Structure, geometry, state: dict, tie_multipliers,
                            data) -> list:
    """The Hessian blocks the dynamics adds to the static Lagrangian's: the centroid ties'
    curvature (``tie_multipliers [3 S]``), the inertia (3 x 3 per segment on ``u``, 3 x 3 per
    segment on ``phi``, 3 x 3 per point) and the joints' damping (6 x 6 per joint)."""
    index = state_index(state)
    weight = 2.0 / data.step**2 + data.mass_damping / data.step
    blocks = []
    if structure.segment_count:
        blocks.append(_tie_curvature_blocks(structure, geometry, state, tie_multipliers))
        centroid = np.asarray(index[CENTROID])
        blocks.append(_block(centroid, centroid, 2.0 * weight * data.translational_mass))
        rotation = np.asarray(index["segment_rotation"])
        rotational = jax.vmap(jax.hessian(rotational_potential),
                              in_axes=(0, 0, 0, 0, 0, 0, None, None))(
            state["segment_rotation"], geometry.frame, data.frame, data.increment_predicted,
            data.angular_rate, data.inertia, weight, data.mass_damping)
        blocks.append(_block(rotation, rotation, rotational))
        blocks.append(_joint_damping_blocks(structure, geometry, state, data, rotation))
    if structure.elements.active:
        points = np.asarray(index["point_position"])
        point_blocks = (2.0 * weight * data.point_mass)[:, None, None] * jnp.eye(3)
        blocks.append(_block(points, points, point_blocks))
    return blocks


def _joint_damping_blocks(structure, geometry, state, data, rotation):
    topology = structure.spring_joint_topology()
    parent, child = np.asarray(topology.parent_segment), np.asarray(topology.child_segment)
    a = np.maximum(parent, 0)
    phi = state["segment_rotation"]
    pair = jnp.concatenate([phi[a], phi[child]], axis=1)
    values = jax.vmap(jax.hessian(joint_damping_potential),
                      in_axes=(0, 0, 0, 0, 0, 0, 0, None))(
        pair, geometry.joint_parent_map, geometry.joint_child_map, parent == GROUND,
        data.joint_rotation, data.joint_rate, data.joint_damping, data.step)
    pair_index = np.concatenate([rotation[a], rotation[child]], axis=1)
    return _block(pair_index, pair_index, values)


def rate_map(state: dict) -> Array:
    """Each segment's body angular velocity per unit rate of its rotation unknowns,
    ``Omega_s = J_r(phi_s) dphi_s/dt`` ``[S, 3, 3]`` (``Q_s = Q_s0 exp(phi_s)``)."""
    return right_jacobian(state["segment_rotation"])


def _rates_objective(rates, args, *, structure):
    """``1/2 |W zdot - v|^2_D + f . zdot`` and the linearised constraints ``J zdot``."""
    state, params, geometry, target, force, translational_mass, mass = args
    terms = 0.5 * jnp.sum(mass.point_mass[:, None] * (_points(rates) - target[2]) ** 2)
    if structure.segment_count:
        du = rates[CENTROID] - target[0]
        omega = jnp.einsum("sij,sj->si", rate_map(state), rates["segment_rotation"])
        dw = omega - target[1]
        terms = terms + 0.5 * (jnp.sum(du * jnp.einsum("sij,sj->si", translational_mass, du))
                               + jnp.sum(mass.segment_inertia * dw * dw))
    terms = terms + ravel_pytree(rates)[0] @ force
    linear = jax.jvp(lambda s: constraints_and_energy(structure, geometry, s, params)[1],
                     (state,), (rates,))[1]
    return terms, linear


def _points(rates):
    return rates.get("point_position", jnp.zeros((0, 3)))


def _rates_hessian(rates, multipliers, args, *, structure):
    state, _, _, _, _, translational_mass, mass = args
    index = state_index(state)
    blocks = []
    if structure.segment_count:
        centroid = np.asarray(index[CENTROID])
        rotation = np.asarray(index["segment_rotation"])
        r = rate_map(state)
        rotational = jnp.einsum("sji,sj,sjk->sik", r, mass.segment_inertia, r)
        blocks += [_block(centroid, centroid, translational_mass),
                   _block(rotation, rotation, rotational)]
    if structure.elements.active:
        points = np.asarray(index["point_position"])
        blocks.append(_block(points, points, mass.point_mass[:, None, None] * jnp.eye(3)))
    return blocks


def constrained_rates(structure: Structure, params, geometry, state: dict, mass,
                      translational_mass, target, force=None, solver: NewtonKKT = NewtonKKT()):
    """The rates ``zdot`` (extended state) minimising ``|W zdot - v|^2_D / 2 + f . zdot``
    subject to the linearised constraints and ties ``J zdot = 0``: the constrained motion's
    velocities closest, in the kinetic-energy norm, to ``target = (centroid velocity [S, 3],
    body angular velocity [S, 3], point velocity [P, 3])`` (with ``f = 0``), or with ``v =
    0`` and ``f = grad E`` the consistent acceleration at rest. A quadratic problem: one
    solve of its KKT system on the route the solver takes for the step (the same blocks and
    factored constraints, with the floor regularisation of an implicit tangent). Returns the
    rates mapped to maximal coordinates ``(centroid [S, 3], angular [S, 3], point [P, 3])``."""
    zero, unravel = ravel_pytree(jax.tree_util.tree_map(jnp.zeros_like, state))
    flat_force = jnp.zeros_like(zero) if force is None else ravel_pytree(force)[0]
    args = (state, params, geometry, target, flat_force, translational_mass, mass)

    def objective(flat, args):
        terms, c = _rates_objective(unravel(flat), args, structure=structure)
        return jnp.reshape(terms, (-1,)), c

    def hessian(flat, multipliers, args):
        return _rates_hessian(unravel(flat), multipliers, args, structure=structure)

    hessian.constraint_pattern = None
    hessian.constraint_factors = (
        (lambda flat, args: step_factors(structure, geometry, params, state))
        if structure.segment_count else None)
    m = jax.eval_shape(objective, zero, args)[1].shape[0]
    multipliers = jnp.zeros((m,))
    route = kkt_route(hessian, solver.linear_solver, args, zero, multipliers)
    kkt = _kkt_at_solution(objective, hessian, route, args, zero, multipliers)
    gradient = jax.grad(lambda flat: jnp.sum(objective(flat, args)[0]))(zero)
    rates = unravel(route.solve(kkt, jnp.concatenate([-gradient, multipliers]))[:zero.size])
    if structure.segment_count:
        centroid = rates[CENTROID]
        angular = jnp.einsum("sij,sj->si", rate_map(state), rates["segment_rotation"])
    else:
        centroid = angular = jnp.zeros((0, 3))
    return centroid, angular, _points(rates)
