"""Implicit time integration: Newmark's average acceleration on SO(3), each step a Newton-KKT
minimisation of an incremental potential.

Maximal coordinates (:mod:`.inertia`) carry the motion: segment centroids ``x``, segment
frames ``Q`` and point positions ``p``. Over a step ``h`` the rotation is updated on the
group, ``Q_{n+1} = Q_n exp(Psi)`` with the material increment ``Psi = log(Q_n^T Q_{n+1})``
(Simo & Wong 1991, *Int. J. Numer. Meth. Eng.* 31, 19-52, their material form), and
translations and increments follow Newmark's average acceleration rule (``beta = 1/4``,
``gamma = 1/2``)::

    x_{n+1} = x_n + h v_n + h^2/4 (a_n + a_{n+1}),      v_{n+1} = v_n + h/2 (a_n + a_{n+1})
    Psi     =       h W_n + h^2/4 (A_n + A_{n+1}),      W_{n+1} = W_n + h/2 (A_n + A_{n+1})

(``W`` body angular velocity, ``A`` its rate). The equations of motion at ``t_{n+1}`` are
then the stationarity conditions of the incremental potential

    Phi(z) = E(z, t_{n+1}) + 2/h^2 [|x(z) - x~|^2_M + |Psi(z) - Psi~|^2_J + |p(z) - p~|^2_m]
             + D(z)

over the solver's state ``z`` under the structure's constraints (``x~ = x_n + h v_n + h^2/4
a_n``, ``Psi~ = h W_n + h^2/4 A_n``): its gradient is ``grad E + M a_{n+1} + ...``, so each
step is one Newton-KKT minimisation (:mod:`.step_newton`: the static solver's stopping rule
and codes, the same constraints, from the quadratic extrapolation of the last three steps;
it must converge, and every step's report is kept), on the state extended
by the segment centroids, with the Hessian assembled block by block and the constraints in
factored form (:mod:`.step_system`). ``D`` is the damping's
incremental potential, whose gradient is the damping force at ``t_{n+1}``: mass-proportional
Rayleigh damping ``c = alpha M`` on every velocity, and stiffness-proportional damping of
the joints, a viscous moment ``beta k_j d(theta_j)/dt`` with ``k_j`` the joint's initial
spring stiffness (its law's initial stiffness over its tributary length).

After each step the velocities are projected, in the kinetic-energy norm, on those the
constrained structure can have (:func:`.step_system.constrained_rates`): Newmark's rule on
constrained maximal coordinates leaves their component across the constraints undetermined.

Properties (tested, tests/test_dynamics_time.py): second order in ``h``; undamped, the
energy oscillates at ``O(h^2)``, never grows, and decays slowly through the projection (at
third order in ``h`` on the pendulum); implicit, so the step is set by the physics to be
resolved, not by the stiffest joint. The gyroscopic moment ``W x J W`` is left out: it is
zero for planar motion and for the axisymmetric segments here unless they spin about their
own axis. The motion starts at rest, with the consistent initial acceleration
(``M a_0 + J^T lambda = -grad E``, ``J a_0 = 0``).

Gradients through the history: each step's solution has the solver's implicit (IFT)
derivative, and ``lax.scan`` carries the tangents from step to step, so ``jax.grad`` of any
function of the history differentiates the discrete equations exactly (a discrete adjoint)
without differentiating a Newton iteration.
"""

from __future__ import annotations

from functools import partial

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .._equilibrium import Solution, tube_reference_geometry
from .._mechanics.energy import energy_terms_and_constraints
from .._mechanics.kinematics import initial_state, spring_joints
from .._mechanics.law_groups import law_groups
from .._rotation import matmul3, rotation_vector, transpose3
from .._solver.newton_kkt import NewtonKKT
from .._structure.structure import GROUND, Structure, StructureParameters
from .inertia import MassProperties, mass_properties, maximal_coordinates, translational_mass
from .loads import parameters_at
from .modes import constraint_count_of, node_positions
from .step_newton import solve_step
from .step_system import (
    CENTROID,
    constrained_rates,
    constraints_and_energy,
    extended_state,
    joint_damping_potential,
    rotational_potential,
    step_factors,
    step_hessian_blocks,
    structure_state,
)


class Damping(eqx.Module):
    """Rayleigh damping: ``mass_proportional`` ``alpha`` [1/s] on every velocity of the
    maximal coordinates, ``stiffness_proportional`` ``beta`` [s] on the joints' rotation
    rates (a viscous moment ``beta k_j dtheta/dt``). A mode of frequency ``omega`` gets the
    damping ratio ``alpha / (2 omega) + beta omega / 2``."""

    mass_proportional: Array = eqx.field(default=0.0, converter=jnp.asarray)
    stiffness_proportional: Array = eqx.field(default=0.0, converter=jnp.asarray)


class History(eqx.Module):
    """A time response; every leaf has a leading ``[K]`` axis over the steps (after the
    initial state, so ``time[0] = h``).

    Attributes:
        time: ``[K]`` [s].
        state: the solver's state at each step.
        node_position: ``[K, N + P0, 3]`` [m] (tube nodes, then point nodes).
        kinetic_energy, potential_energy: ``[K]`` [J] (the potential of the loads at that
            time; without time-varying loads their sum is the mechanical energy).
        line_length: ``[K, L]`` [m].
        converged, iterations, result, residual: each step's solver report.
    """

    time: Array
    state: dict
    node_position: Array
    kinetic_energy: Array
    potential_energy: Array
    line_length: Array
    converged: Array
    iterations: Array
    result: Array
    residual: Array


class _Motion(eqx.Module):
    """Velocities and accelerations of the maximal coordinates (body frame for rotations)."""

    velocity: Array  # [S, 3]
    acceleration: Array  # [S, 3]
    angular_velocity: Array  # [S, 3] body frame
    angular_acceleration: Array  # [S, 3]
    point_velocity: Array  # [P, 3]
    point_acceleration: Array  # [P, 3]
    joint_rotation: Array  # [J, 3]
    joint_rate: Array  # [J, 3]


class _StepData(eqx.Module):
    """What one step's incremental potential needs besides the state."""

    step: Array  # h [s]
    centroid_predicted: Array  # x~ [S, 3]
    centroid_rate: Array  # v_n + h/2 a_n [S, 3]
    translational_mass: Array  # [S, 3, 3]
    frame: Array  # Q_n [S, 3, 3]
    increment_predicted: Array  # Psi~ [S, 3]
    angular_rate: Array  # W_n + h/2 A_n [S, 3]
    inertia: Array  # [S, 3]
    point_predicted: Array  # p~ [P, 3]
    point_rate: Array  # [P, 3]
    point_mass: Array  # [P]
    joint_rotation: Array  # theta_n [J, 3]
    joint_rate: Array  # thetadot_n [J, 3]
    joint_damping: Array  # beta k_j [J, 3]
    mass_damping: Array  # alpha


def joint_stiffness(structure: Structure, params: StructureParameters, geometry) -> Array:
    """Initial rotational stiffness of each spring joint ``[J, 3]`` [N m/rad]: the laws'
    initial stiffness (bending twice, torsion) over the tributary length."""
    topology = structure.spring_joint_topology()
    count = len(topology.node)
    stiffness = jnp.zeros((count, 3))
    radius_all = params.node_radius[np.array(topology.node, dtype=np.int32)]
    for group in law_groups(topology.law, params.bending_laws, params.torsion_laws):
        idx = group.joints
        pressure, radius = group.per_joint(params.pressure), radius_all[idx]
        shape = (len(idx),)
        bend = jnp.broadcast_to(group.apply(group.law(params.bending_laws),
                                            "initial_stiffness", pressure, radius), shape)
        twist = jnp.broadcast_to(group.apply(group.law(params.torsion_laws),
                                             "initial_stiffness", pressure, radius), shape)
        stiffness = stiffness.at[idx].set(jnp.stack([bend, bend, twist], axis=-1))
    return stiffness / geometry.joint_tributary[:, None]


def _joint_rotation(structure, geometry, state) -> Array:
    if not structure.segment_count:
        return jnp.zeros((0, 3))
    return spring_joints(structure, geometry, state).rotation


def _quadratic(delta: Array, weight: Array) -> Array:
    """``sum delta . weight delta`` for ``weight`` ``[..., 3, 3]`` or ``[..., 3]``."""
    if weight.ndim == delta.ndim + 1:
        return jnp.sum(delta * jnp.einsum("sij,sj->si", weight, delta))
    return jnp.sum(weight * delta * delta)


def _inertial_potential(structure, geometry, state, data: _StepData) -> Array:
    """The incremental potential's inertial and damping part [J] (module docstring) at an
    extended state (:mod:`.step_system`: the centroids are unknowns)."""
    h = data.step
    weight = 2.0 / h**2 + data.mass_damping / h
    potential = jnp.zeros(())
    if structure.segment_count:
        dx = state[CENTROID] - data.centroid_predicted
        potential = (weight * _quadratic(dx, data.translational_mass)
                     + data.mass_damping * jnp.sum(
                         data.centroid_rate * jnp.einsum("sij,sj->si",
                                                         data.translational_mass, dx)))
        potential = potential + jnp.sum(jax.vmap(
            rotational_potential, in_axes=(0, 0, 0, 0, 0, 0, None, None))(
            state["segment_rotation"], geometry.frame, data.frame, data.increment_predicted,
            data.angular_rate, data.inertia, weight, data.mass_damping))
        topology = structure.spring_joint_topology()
        parent = np.asarray(topology.parent_segment)
        phi = state["segment_rotation"]
        pair = jnp.concatenate([phi[np.maximum(parent, 0)],
                                phi[np.asarray(topology.child_segment)]], axis=1)
        potential = potential + jnp.sum(jax.vmap(
            joint_damping_potential, in_axes=(0, 0, 0, 0, 0, 0, 0, None))(
            pair, geometry.joint_parent_map, geometry.joint_child_map, parent == GROUND,
            data.joint_rotation, data.joint_rate, data.joint_damping, h))
    if structure.elements.active:
        dp = state["point_position"] - data.point_predicted
        potential = potential + jnp.sum(data.point_mass[:, None] * (
            weight * dp * dp + data.mass_damping * data.point_rate * dp))
    return potential


def _step_objective(state, args, *, structure):
    params, geometry, data = args
    terms, c = constraints_and_energy(structure, geometry, state, params)
    inertial = _inertial_potential(structure, geometry, state, data)
    return jnp.concatenate([terms, inertial[None]]), c


def _step_hessian(state, multipliers, args, *, structure):
    params, geometry, data = args
    return step_hessian_blocks(structure, geometry, params, state, multipliers, data)


def _step_factors(state, args, *, structure):
    params, geometry, _ = args
    return step_factors(structure, geometry, params, state)


def _kinetic_energy(mass: MassProperties, frame, motion: _Motion) -> Array:
    return 0.5 * (_quadratic(motion.velocity, translational_mass(mass, frame))
                  + _quadratic(motion.angular_velocity, mass.segment_inertia)
                  + jnp.sum(mass.point_mass[:, None] * motion.point_velocity**2))


def _rest_acceleration(structure, params, geometry, state, mass, frame, solver) -> _Motion:
    """The motion at rest with the consistent acceleration: ``M a + J^T mu = -grad E``,
    ``J a = 0`` (velocities zero, so no velocity terms), in maximal coordinates."""
    gradient = jax.grad(lambda s: jnp.sum(constraints_and_energy(structure, geometry, s,
                                                                 params)[0]))(state)
    s, p = structure.segment_count, structure.elements.unknown_count
    zeros = jnp.zeros((s, 3))
    acceleration, angular, point = constrained_rates(
        structure, params, geometry, state, mass, translational_mass(mass, frame),
        (zeros, zeros, jnp.zeros((p, 3))), force=gradient, solver=solver)
    joints = _joint_rotation(structure, geometry, state)
    return _Motion(velocity=zeros, acceleration=acceleration, angular_velocity=zeros,
                   angular_acceleration=angular, point_velocity=jnp.zeros((p, 3)),
                   point_acceleration=point, joint_rotation=joints,
                   joint_rate=jnp.zeros_like(joints))


def simulate_dynamics(structure: Structure, params: StructureParameters, time_step,
                      steps: int, initial: Solution | None = None, loads: tuple = (),
                      support_motions: tuple = (), damping: Damping = Damping(),
                      solver: NewtonKKT = NewtonKKT()) -> History:
    """The response over ``steps`` steps of ``time_step`` [s] from rest at ``initial`` (a
    :class:`jaxtube.Solution`, e.g. the static equilibrium; default the reference state),
    under the static loads of ``params`` plus ``loads`` (:class:`DynamicLoad`) and
    ``support_motions`` (:class:`SupportMotion`), with ``damping`` (:class:`Damping`).

    Newmark's average acceleration on SO(3) with each step a Newton-KKT solve (module
    docstring; ``solver``'s tolerances and caps apply to each step). Every step reports
    ``converged``; a step that fails is kept and reported, never passed over
    (:func:`jaxtube.check_converged` names them). Differentiable in ``params`` (and the
    loads) by the implicit function theorem per step. The model must give every free
    unknown some mass. ``steps`` is static.

    Example::

        load = jt.dynamic_load(structure, params, {"tube:end": [0, 0, -5]}, jt.StepFunction())
        history = jt.simulate_dynamics(structure, params, 1e-3, 1000, loads=(load,))
    """
    # The step is an array, so that a new step size does not compile a new program.
    return _simulate(structure, params, jnp.asarray(time_step, dtype=float), steps, initial,
                     loads, support_motions, damping, solver)


@eqx.filter_jit
def _simulate(structure, params, time_step, steps, initial, loads, support_motions, damping,
              solver) -> History:
    geometry = tube_reference_geometry(structure, params)
    h = jnp.asarray(time_step, dtype=float)
    state = initial_state(structure, params) if initial is None else initial.state
    m = constraint_count_of(structure, params, state)
    multipliers = jnp.concatenate([jnp.zeros((m,)) if initial is None
                                   else initial.multipliers[:m],
                                   jnp.zeros((3 * structure.segment_count,))])
    state = extended_state(structure, geometry, state)
    params0 = parameters_at(params, loads, support_motions, jnp.zeros(()))
    mass = mass_properties(structure, params, geometry)
    start = maximal_coordinates(structure, geometry, state)
    motion = _rest_acceleration(structure, params0, geometry, state, mass, start.frame, solver)
    beta_k = damping.stiffness_proportional * (joint_stiffness(structure, params, geometry)
                                               if structure.segment_count else jnp.zeros((0, 3)))
    objective, hessian, factors = (partial(model, structure=structure) for model in
                                   (_step_objective, _step_hessian, _step_factors))
    factors = factors if structure.segment_count else None

    def one_step(carry, index):
        (state, multipliers), past, motion = carry
        time = (index + 1.0) * h
        params_t = parameters_at(params, loads, support_motions, time)
        here = maximal_coordinates(structure, geometry, state)
        quarter = h**2 / 4
        weight = translational_mass(mass, here.frame)
        data = _StepData(
            step=h,
            centroid_predicted=here.centroid + h * motion.velocity + quarter * motion.acceleration,
            centroid_rate=motion.velocity + h / 2 * motion.acceleration,
            translational_mass=weight,
            frame=here.frame,
            increment_predicted=h * motion.angular_velocity + quarter * motion.angular_acceleration,
            angular_rate=motion.angular_velocity + h / 2 * motion.angular_acceleration,
            inertia=mass.segment_inertia,
            point_predicted=(here.point + h * motion.point_velocity
                             + quarter * motion.point_acceleration),
            point_rate=motion.point_velocity + h / 2 * motion.point_acceleration,
            point_mass=mass.point_mass,
            joint_rotation=motion.joint_rotation, joint_rate=motion.joint_rate,
            joint_damping=beta_k, mass_damping=damping.mass_proportional)
        guess = _extrapolated((state, multipliers), *past)
        solved = solve_step(objective, guess[0], (params_t, geometry, data), solver, guess[1],
                            hessian, factors)
        there = maximal_coordinates(structure, geometry, solved.state)
        acceleration = 4.0 / h**2 * (there.centroid - data.centroid_predicted)
        psi = rotation_vector(matmul3(transpose3(here.frame), there.frame))
        angular_acceleration = 4.0 / h**2 * (psi - data.increment_predicted)
        point_acceleration = 4.0 / h**2 * (there.point - data.point_predicted)
        joints = _joint_rotation(structure, geometry, solved.state)
        # Newmark's velocities, projected on those the constrained structure can have.
        target = (motion.velocity + h / 2 * (motion.acceleration + acceleration),
                  motion.angular_velocity + h / 2 * (motion.angular_acceleration
                                                     + angular_acceleration),
                  motion.point_velocity + h / 2 * (motion.point_acceleration
                                                   + point_acceleration))
        velocity, angular_velocity, point_velocity = constrained_rates(
            structure, params_t, geometry, solved.state, mass,
            translational_mass(mass, there.frame), target, solver=solver)
        new = _Motion(
            velocity=velocity,
            acceleration=acceleration,
            angular_velocity=angular_velocity,
            angular_acceleration=angular_acceleration,
            point_velocity=point_velocity,
            point_acceleration=point_acceleration,
            joint_rotation=joints,
            joint_rate=2.0 / h * (joints - motion.joint_rotation) - motion.joint_rate)
        own = structure_state(solved.state)
        terms, _ = energy_terms_and_constraints(structure, geometry, own, params_t, None)
        record = dict(time=time, state=own,
                      node_position=node_positions(structure, geometry, own),
                      kinetic_energy=_kinetic_energy(mass, there.frame, new),
                      potential_energy=jnp.sum(terms), line_length=_line_lengths(structure, own),
                      converged=solved.converged, iterations=solved.iterations,
                      result=solved.result, residual=solved.residual)
        return ((solved.state, solved.multipliers), ((state, multipliers), past[0]), new), record

    start = (state, multipliers)
    _, record = jax.lax.scan(one_step, (start, (start, start), motion),
                             jnp.arange(steps, dtype=float))
    return History(**record)


def _extrapolated(last, before, earlier):
    """The quadratic extrapolation ``3 z_n - 3 z_{n-1} + z_{n-2}`` of the solver's state and
    multipliers over the last three steps (PyTrees of the same structure): the first guess of
    the next step's Newton iteration, off by ``O(h^3)`` of a smooth motion where the last
    solution is off by ``O(h)`` (fewer Newton iterations; the solution does not depend on it)."""
    return jax.tree.map(lambda a, b, c: 3.0 * (a - b) + c, last, before, earlier)


def _line_lengths(structure: Structure, state: dict) -> Array:
    ends = structure.elements.line_ends
    if not ends:
        return jnp.zeros((0,))
    ends = np.asarray(ends, dtype=np.int32)
    points = state["point_position"]
    return jnp.linalg.norm(points[ends[:, 0]] - points[ends[:, 1]], axis=-1)
