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
step is one call of the static Newton-KKT solver (the same constraints, warm-started from
the last step; it must converge, and every step's report is kept). ``D`` is the damping's
incremental potential, whose gradient is the damping force at ``t_{n+1}``: mass-proportional
Rayleigh damping ``c = alpha M`` on every velocity, and stiffness-proportional damping of
the joints, a viscous moment ``beta k_j d(theta_j)/dt`` with ``k_j`` the joint's initial
spring stiffness (its law's initial stiffness over its tributary length).

After each step the velocities are projected, in the kinetic-energy norm, on those the
constrained structure can have (:func:`admissible_velocities`): Newmark's rule on
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
from jax.flatten_util import ravel_pytree

from .._equilibrium import Solution, tube_reference_geometry
from .._mechanics.energy import energy_terms_and_constraints
from .._mechanics.kinematics import initial_state, spring_joints
from .._mechanics.law_groups import law_groups
from .._rotation import matmul3, rotation_vector, transpose3
from .._solver.newton_kkt import NewtonKKT, solve_equilibrium
from .._structure.structure import Structure, StructureParameters
from .inertia import (
    MassProperties,
    mass_matrix,
    mass_properties,
    maximal_coordinates,
    translational_mass,
    velocity_map,
)
from .loads import parameters_at
from .modes import constraint_count_of, node_positions


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
    """The incremental potential's inertial and damping part [J] (module docstring)."""
    here = maximal_coordinates(structure, geometry, state)
    h = data.step
    dx = here.centroid - data.centroid_predicted
    psi = rotation_vector(matmul3(transpose3(data.frame), here.frame))
    dpsi = psi - data.increment_predicted
    dp = here.point - data.point_predicted
    inertial = (_quadratic(dx, data.translational_mass) + _quadratic(dpsi, data.inertia)
                + jnp.sum(data.point_mass[:, None] * dp * dp))
    rate_work = (jnp.sum(data.centroid_rate * jnp.einsum("sij,sj->si",
                                                         data.translational_mass, dx))
                 + jnp.sum(data.angular_rate * data.inertia * dpsi)
                 + jnp.sum(data.point_rate * data.point_mass[:, None] * dp))
    potential = 2.0 / h**2 * inertial + data.mass_damping * (inertial / h + rate_work)
    dtheta = _joint_rotation(structure, geometry, state) - data.joint_rotation
    return potential + jnp.sum(data.joint_damping * (dtheta * dtheta / h
                                                     - data.joint_rate * dtheta))


def _step_objective(state, args, *, structure):
    params, geometry, data = args
    terms, c = energy_terms_and_constraints(structure, geometry, state, params, None)
    inertial = _inertial_potential(structure, geometry, state, data)
    return jnp.concatenate([terms, inertial[None]]), c


def _kinetic_energy(mass: MassProperties, frame, motion: _Motion) -> Array:
    return 0.5 * (_quadratic(motion.velocity, translational_mass(mass, frame))
                  + _quadratic(motion.angular_velocity, mass.segment_inertia)
                  + jnp.sum(mass.point_mass[:, None] * motion.point_velocity**2))


def admissible_velocities(structure, params, geometry, state, mass: MassProperties,
                          velocity, angular_velocity, point_velocity):
    """The closest velocities (in the kinetic-energy norm) that the structure can have at
    ``state``: ``W zdot`` with ``zdot`` minimising ``|W zdot - v|_D`` subject to
    ``J zdot = 0``. Newmark's rule on maximal coordinates under constraints leaves the
    velocity's component across the constraints undetermined (a double eigenvalue -1 of
    the step: it grows linearly); projecting it away every step keeps the velocities those
    of the constrained motion."""
    z, unravel = ravel_pytree(state)
    w = velocity_map(structure, geometry, state)
    here = maximal_coordinates(structure, geometry, state)
    s = structure.segment_count
    n = z.shape[0]
    translation = w[: 3 * s].reshape(s, 3, n)
    rotation = w[3 * s: 6 * s].reshape(s, 3, n)
    points = w[6 * s:].reshape(-1, 3, n)
    weight = translational_mass(mass, here.frame)
    mass_matrix_ = (jnp.einsum("sim,sij,sjn->mn", translation, weight, translation)
                    + jnp.einsum("sim,si,sin->mn", rotation, mass.segment_inertia, rotation)
                    + jnp.einsum("pim,p,pin->mn", points, mass.point_mass, points))
    momentum = (jnp.einsum("sim,sij,sj->m", translation, weight, velocity)
                + jnp.einsum("sim,si,si->m", rotation, mass.segment_inertia, angular_velocity)
                + jnp.einsum("pim,p,pi->m", points, mass.point_mass, point_velocity))

    def constraint_values(flat):
        s_ = unravel(flat)
        return energy_terms_and_constraints(structure, geometry, s_, params, None)[1]

    jacobian = jax.jacfwd(constraint_values)(z)
    m = jacobian.shape[0]
    system = jnp.block([[mass_matrix_, jacobian.T], [jacobian, jnp.zeros((m, m))]])
    rates = jnp.linalg.solve(system, jnp.concatenate([momentum, jnp.zeros(m)]))[:n]
    projected = w @ rates
    return (projected[: 3 * s].reshape(s, 3), projected[3 * s: 6 * s].reshape(s, 3),
            projected[6 * s:].reshape(-1, 3))


def _rest_acceleration(structure, params, geometry, state, multipliers) -> _Motion:
    """The motion at rest with the consistent acceleration: ``[M J^T; J 0] [zdd; mu] =
    [-grad E; 0]`` (velocities zero, so no velocity terms), mapped to maximal coordinates."""
    z, unravel = ravel_pytree(state)

    def objective(flat):
        s = unravel(flat)
        terms, c = energy_terms_and_constraints(structure, geometry, s, params, None)
        return jnp.sum(terms), c

    gradient = jax.grad(lambda f: objective(f)[0])(z)
    jacobian = jax.jacfwd(lambda f: objective(f)[1])(z)
    mass = mass_matrix(structure, params, geometry, state)
    n, m = z.shape[0], jacobian.shape[0]
    system = jnp.block([[mass, jacobian.T], [jacobian, jnp.zeros((m, m))]])
    solution = jnp.linalg.solve(system, jnp.concatenate([-gradient, jnp.zeros(m)]))
    maximal = velocity_map(structure, geometry, state) @ solution[:n]
    s, p = structure.segment_count, structure.elements.unknown_count
    joints = _joint_rotation(structure, geometry, state)
    zeros = jnp.zeros((s, 3))
    return _Motion(velocity=zeros, acceleration=maximal[: 3 * s].reshape(s, 3),
                   angular_velocity=zeros,
                   angular_acceleration=maximal[3 * s: 6 * s].reshape(s, 3),
                   point_velocity=jnp.zeros((p, 3)),
                   point_acceleration=maximal[6 * s:].reshape(p, 3),
                   joint_rotation=joints, joint_rate=jnp.zeros_like(joints))


def simulate_dynamics(structure: Structure, params: StructureParameters, time_step,
                      steps: int, initial: Solution | None = None, loads: tuple = (),
                      support_motions: tuple = (), damping: Damping = Damping(),
                      solver: NewtonKKT = NewtonKKT()) -> History:
    """The response over ``steps`` steps of ``time_step`` [s] from rest at ``initial`` (a
    :class:`jaxtube.Solution`, e.g. the static equilibrium; default the reference state),
    under the static loads of ``params`` plus ``loads`` (:class:`DynamicLoad`) and
    ``support_motions`` (:class:`SupportMotion`), with ``damping`` (:class:`Damping`).

    Newmark's average acceleration on SO(3) with each step a Newton-KKT solve (module
    docstring). Every step reports ``converged``; a step that fails is kept and reported,
    never passed over (:func:`jaxtube.check_converged` names them). Differentiable in
    ``params`` (and the loads) by the implicit function theorem per step. The model must
    give every free unknown some mass. ``steps`` is static.

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
    multipliers = (jnp.zeros((m,)) if initial is None else initial.multipliers[:m])
    params0 = parameters_at(params, loads, support_motions, jnp.zeros(()))
    motion = _rest_acceleration(structure, params0, geometry, state, multipliers)
    mass = mass_properties(structure, params, geometry)
    beta_k = damping.stiffness_proportional * (joint_stiffness(structure, params, geometry)
                                               if structure.segment_count else jnp.zeros((0, 3)))

    def one_step(carry, index):
        state, multipliers, motion = carry
        time = (index + 1.0) * h
        params_t = parameters_at(params, loads, support_motions, time)
        here = maximal_coordinates(structure, geometry, state)
        quarter = h**2 / 4
        data = _StepData(
            step=h,
            centroid_predicted=here.centroid + h * motion.velocity + quarter * motion.acceleration,
            centroid_rate=motion.velocity + h / 2 * motion.acceleration,
            translational_mass=translational_mass(mass, here.frame),
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
        objective = partial(_step_objective, structure=structure)
        solved = solve_equilibrium(objective, state, (params_t, geometry, data), solver,
                                   multipliers)
        there = maximal_coordinates(structure, geometry, solved.state)
        acceleration = 4.0 / h**2 * (there.centroid - data.centroid_predicted)
        psi = rotation_vector(matmul3(transpose3(here.frame), there.frame))
        angular_acceleration = 4.0 / h**2 * (psi - data.increment_predicted)
        point_acceleration = 4.0 / h**2 * (there.point - data.point_predicted)
        joints = _joint_rotation(structure, geometry, solved.state)
        velocity, angular_velocity, point_velocity = admissible_velocities(
            structure, params_t, geometry, solved.state, mass,
            motion.velocity + h / 2 * (motion.acceleration + acceleration),
            motion.angular_velocity + h / 2 * (motion.angular_acceleration
                                               + angular_acceleration),
            motion.point_velocity + h / 2 * (motion.point_acceleration + point_acceleration))
        new = _Motion(
            velocity=velocity,
            acceleration=acceleration,
            angular_velocity=angular_velocity,
            angular_acceleration=angular_acceleration,
            point_velocity=point_velocity,
            point_acceleration=point_acceleration,
            joint_rotation=joints,
            joint_rate=2.0 / h * (joints - motion.joint_rotation) - motion.joint_rate)
        terms, _ = energy_terms_and_constraints(structure, geometry, solved.state, params_t,
                                                None)
        lengths = _line_lengths(structure, solved.state)
        record = dict(time=time, state=solved.state,
                      node_position=node_positions(structure, geometry, solved.state),
                      kinetic_energy=_kinetic_energy(mass, there.frame, new),
                      potential_energy=jnp.sum(terms), line_length=lengths,
                      converged=solved.converged, iterations=solved.iterations,
                      result=solved.result, residual=solved.residual)
        return (solved.state, solved.multipliers, new), record

    _, record = jax.lax.scan(one_step, (state, multipliers, motion),
                             jnp.arange(steps, dtype=float))
    return History(**record)


def _line_lengths(structure: Structure, state: dict) -> Array:
    ends = structure.elements.line_ends
    if not ends:
        return jnp.zeros((0,))
    ends = np.asarray(ends, dtype=np.int32)
    points = state["point_position"]
    return jnp.linalg.norm(points[ends[:, 0]] - points[ends[:, 1]], axis=-1)
