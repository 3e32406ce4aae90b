"""Load paths: :func:`solve_path` steps through a :class:`ForceControl` or a
:class:`DisplacementControl` inside ``jit``; :func:`drive_to_dead_load` reaches a dead
load on one node through displacement control of that node.

The path is a ``lax.scan`` over steps; every step's solution carries its own convergence
flag. Each step starts from a *secant predictor* (:func:`secant_start`): the last two
converged solutions extrapolated linearly to the step's load factor or displacement, the
predictor of pseudo-arclength continuation without its corrector (Allgower & Georg 2003,
*Introduction to Numerical Continuation Methods*, ch. 2). Newton then starts at a distance of
second order in the step rather than first: on the 50-step curve through collapse of
``experiments/bench_solver.py`` the Newton steps fell from 160 to 119 and the time by about a
fifth (``docs/performance.md``). Gradients w.r.t. the parameters come by the implicit function
theorem at every step, and do not depend on the start.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array

from ._controls import DisplacementControl, ForceControl, scale_loads
from ._equilibrium import Solution, constraint_count, solve_load_level, tube_reference_geometry
from ._mechanics.kinematics import initial_state
from ._solver.newton_kkt import NewtonKKT
from ._structure.structure import Structure, StructureParameters

#: Largest step of the secant predictor, relative to the last step (:func:`secant_start`).
MAX_EXTRAPOLATION = 2.0

#: ``solve_path``'s ``predictor`` settings.
PREDICTORS = ("secant", "previous")


def secant_start(current, previous, value, value_now, value_before, usable):
    """The start of the next step: ``current + r (current - previous)`` with
    ``r = (value - value_now) / (value_now - value_before)`` clipped to
    ``[-MAX_EXTRAPOLATION, MAX_EXTRAPOLATION]``, where ``current`` and ``previous`` are the
    solutions (any matching PyTrees: states, multipliers) at the path values ``value_now``
    and ``value_before``; ``current`` itself where ``usable`` is False (fewer than two
    converged solutions) or the two values coincide. Traceable; ``usable`` may be batched."""
    span = value_now - value_before
    ratio = jnp.where(usable & (span != 0.0),
                      (value - value_now) / jnp.where(span != 0.0, span, 1.0), 0.0)
    ratio = jnp.clip(ratio, -MAX_EXTRAPOLATION, MAX_EXTRAPOLATION)
    return jax.tree_util.tree_map(lambda a, b: a + ratio * (a - b), current, previous)


def solve_path(
    structure: Structure,
    params: StructureParameters,
    path: ForceControl | DisplacementControl,
    solver: NewtonKKT = NewtonKKT(),
    predictor: str = "secant",
) -> Solution:
    """Follow a load path by stepping (``lax.scan``); returns a :class:`Solution` whose
    leaves have a leading step axis ``[K]``, each step reporting its own convergence.

    ``predictor``: where each step's Newton iteration starts: ``"secant"`` (default: the
    last two converged solutions extrapolated to the step's value, :func:`secant_start`) or
    ``"previous"`` (the last solution). Both reach the same equilibria where the path has
    one branch; the secant needs fewer Newton steps on smooth stretches."""
    if predictor not in PREDICTORS:
        raise ValueError(f"predictor must be one of {PREDICTORS}, got {predictor!r}")
    geometry = tube_reference_geometry(structure, params)
    state0 = initial_state(structure, params)
    m_support = constraint_count(structure)

    if isinstance(path, DisplacementControl):
        lam0 = jnp.zeros((m_support + 1,))

        def solve(start, value):
            ctrl = (path.node, path.direction, value)
            return solve_load_level(structure, params, geometry, ctrl, start[0], start[1],
                                    solver, 1.0)

        values = path.displacements
    else:
        lam0 = jnp.zeros((m_support,))

        def solve(start, factor):
            return solve_load_level(structure, scale_loads(params, factor), geometry, None,
                                    start[0], start[1], solver, factor)

        values = path.load_factors

    def step(carry, value):
        current, previous, value_now, value_before, now_ok, before_ok = carry
        start = secant_start(current, previous, value, value_now, value_before,
                             now_ok & before_ok & (predictor == "secant"))
        sol = solve(start, value)
        return ((sol.state, sol.multipliers), current, value, value_now, sol.converged,
                now_ok), sol

    zero = jnp.zeros((), float)
    no = jnp.zeros((), bool)
    init = ((state0, lam0), (state0, lam0), zero, zero, no, no)
    _, sols = jax.lax.scan(step, init, values)
    return sols


class DrivenEquilibrium(eqx.Module):
    """A dead load reached through displacement control (:func:`drive_to_dead_load`).

    Attributes:
        equilibrium: the :class:`Solution` under the dead load (a force-control solve from
            the driven state; its ``converged`` is the solver's own verdict).
        start: the controlled solve at the start's own displacement (from ``initial``: no
            Newton step where it is an equilibrium without the driven load; from the
            undeformed shape: the other loads' equilibrium with the node held there).
        path: the displacement-controlled steps, leaves with a leading ``[K]`` axis, ``K``
            the ``steps`` allowed (``control_displacement`` [m], ``control_force`` [N], each
            step's convergence; a refused step reports ``converged`` False and leaves the
            drive where it was; steps after ``steps_taken`` are zeros, not converged).
        target_force: the dead load's component along the drive direction [N].
        reached: whether a converged controlled step carried ``target_force`` (to
            ``force_tolerance``) before the equilibrium solve.
        steps_taken: the controlled steps solved (the first ``steps_taken`` of ``path``).
    """

    equilibrium: Solution
    start: Solution
    path: Solution
    target_force: Array
    reached: Array
    steps_taken: Array


def _node_reference(structure: Structure, params: StructureParameters, node: int) -> Array:
    """Undeformed position ``[3]`` [m] of a global node (tube node or point node)."""
    if node < structure.node_count:
        return params.node_position[node]
    return params.elements.point_position[node - structure.node_count]


def node_dead_load(structure: Structure, params: StructureParameters, node: int) -> Array:
    """The dead point force ``[3]`` [N] on a global node: a tube node's ``node_force`` or a
    free point node's ``point_force``."""
    if node < structure.node_count:
        return params.node_force[node]
    row = node - structure.node_count
    if row >= params.elements.point_force.shape[0]:
        raise ValueError(f"node {node}: not a tube node or a free point node of the structure "
                         f"(0..{structure.node_count + params.elements.point_force.shape[0] - 1})")
    return params.elements.point_force[row]


def with_node_dead_load(structure: Structure, params: StructureParameters, node: int,
                        force) -> StructureParameters:
    """``params`` with the dead point force on global ``node`` set to ``force`` ``[3]`` [N]."""
    node_dead_load(structure, params, node)  # validates the node
    force = jnp.asarray(force, dtype=float)
    if node < structure.node_count:
        return eqx.tree_at(lambda p: p.node_force, params, params.node_force.at[node].set(force))
    row = node - structure.node_count
    return eqx.tree_at(lambda p: p.elements.point_force, params,
                       params.elements.point_force.at[row].set(force))


def drive_to_dead_load(
    structure: Structure,
    params: StructureParameters,
    node: int,
    direction,
    initial: Solution | None = None,
    solver: NewtonKKT = NewtonKKT(),
    steps: int = 24,
    max_increment: float = 0.1,
    force_tolerance: float = 1e-6,
) -> DrivenEquilibrium:
    """The equilibrium under ``params``' dead loads, reached by driving ``node`` along
    ``direction`` until the actuator carries that node's dead load.

    Why: force control steps the load and asks Newton for the displacement; where the
    structure is soft in the load's direction, or the set of taut lines changes on the way,
    Newton from the previous load level may not find the next equilibrium although it exists
    (the V3 kite's 25 kg centre load: experiments/README). Displacement control of the loaded
    node is stiff in that direction, and its equilibria coincide with the dead-load ones: with
    the constraint ``(x - X) . d = u`` the stationarity conditions are those of the dead load
    ``W d`` at ``node`` exactly when the constraint's reaction (``control_force``) equals
    ``W``. So the drive solves the scalar equation ``control_force(u) = W``:

    1. The node's dead load component ``W = f . d`` is taken out of ``params`` (the rest of
       the load acts as given) and the node starts at ``initial``'s displacement ``u0``.
    2. At most ``steps`` controlled solves (a ``lax.while_loop`` that ends once the drive
       carries the load): Newton's method on the scalar equation, ``du = (W - F) / k`` with
       ``k = dF/du`` the tangent stiffness at the last accepted solve (implicit function
       theorem: one more linear solve with its KKT matrix), ``|du| <= max_increment`` [m];
       where ``k`` is not positive (a snap-through: ``F`` falls as ``u`` grows) or not known
       (the start did not converge), a full ``max_increment`` towards ``W``. Each solve starts
       from the tangent predictor ``y + du dy/du`` of the last accepted one (the predictor of
       pseudo-arclength continuation, Allgower & Georg 2003, ch. 2). A refused step (not
       converged) halves the increment and keeps the drive where it was. The drive stops
       once ``|F - W| <= force_tolerance * max(|W|, 1 N)``. The start (1.'s state at ``u0``)
       is the loop's first pass, so the program holds one controlled solve, not three (each
       traced solve is a copy of the Newton iteration to compile).
    3. The dead-load problem (``params`` as given) is solved from the driven state: the
       equilibrium reported, with the solver's own stopping rule (Newton starts within
       ``force_tolerance`` of it).

    Not covered: a snap-back (``u`` itself turning back along the path) needs an arc-length
    method; the drive then stops short of ``W`` (``reached`` False) and the equilibrium solve
    says whether Newton found the dead-load equilibrium from there.

    Args:
        node: global node index (a tube node or a free point node) carrying the dead load.
        direction: ``[3]`` drive direction (normalised here); the load's component along it
            is driven, its other components act as dead loads throughout.
        initial: a :class:`Solution` of the same structure without the node's load along
            ``direction`` (e.g. the gravity hang) to start from; ``None``: the undeformed
            shape, ``u0 = 0`` (the loop's first solve then finds the other loads'
            equilibrium with the node held at its undeformed position).
        steps: the most controlled solves (a static count: one compiled program).
        max_increment: largest drive increment [m] per step.
        force_tolerance: relative force mismatch at which the drive stops.

    Returns a :class:`DrivenEquilibrium`. Traceable (``jit``); gradients w.r.t. ``params``
    flow through the equilibrium solve by the implicit function theorem (the drive only
    supplies its start).
    """
    direction = jnp.asarray(direction, dtype=float)
    direction = direction / jnp.linalg.norm(direction)
    load = node_dead_load(structure, params, node)
    target = jnp.dot(load, direction)
    driven_params = with_node_dead_load(structure, params, node, load - target * direction)
    geometry = tube_reference_geometry(structure, params)
    reference = _node_reference(structure, params, node)
    m_support = constraint_count(structure)
    if initial is None:
        state0, lam0 = initial_state(structure, params), jnp.zeros((m_support,))
        u0 = jnp.zeros(())
    else:
        state0, lam0 = initial.state, initial.multipliers
        u0 = jnp.dot(initial.node_position[node] - reference, direction)
    state0, lam0, u0 = jax.lax.stop_gradient((state0, lam0, u0))

    # The drive only supplies the start of the equilibrium solve: no gradient through it.
    path_params, path_geometry = jax.lax.stop_gradient((driven_params, geometry))

    def controlled(state, lam, u):
        """The controlled solve from ``(state, lam)`` at ``u`` and its tangent along ``u``
        (implicit function theorem: one more linear solve)."""
        return jax.jvp(lambda v: solve_load_level(structure, path_params, path_geometry,
                                                  (node, direction, v), state, lam, solver,
                                                  1.0), (u,), (jnp.ones_like(u),))

    # One controlled solve in the program (each traced solve is a copy of the Newton
    # iteration to compile): the loop's first pass is the start itself (at its own
    # displacement: no Newton step); the loop ends once the drive carries the load.
    target_force = jax.lax.stop_gradient(target)  # (the loop is not differentiated)
    tolerance = force_tolerance * jnp.maximum(jnp.abs(target_force), 1.0)
    lam_start = jnp.concatenate([lam0, jnp.zeros((1,))])
    shapes = jax.eval_shape(lambda: controlled(state0, lam_start, u0)[0])
    empty = jax.tree_util.tree_map(lambda x: jnp.zeros((steps + 1,) + x.shape, x.dtype),
                                   shapes)

    def step(carry):
        (k, state, lam, rate, u, force, stiffness, increment, done, path) = carry
        started = k > 0
        toward = jnp.where(stiffness > 0.0,
                           (target_force - force) / jnp.where(stiffness > 0.0, stiffness, 1.0),
                           jnp.sign(target_force - force) * increment)
        du = jnp.where(started, jnp.clip(toward, -increment, increment), 0.0)
        start = jax.tree_util.tree_map(lambda x, dx: x + du * dx, (state, lam), rate)
        trial, trial_rate = controlled(*start, u + du)
        accepted = trial.converged | ~started  # (the start is taken as it is)
        pick = lambda new, old: jax.tree_util.tree_map(  # noqa: E731
            lambda a, b: jnp.where(accepted, a, b), new, old)
        tangent_known = trial.converged
        new_rate = jax.tree_util.tree_map(lambda d: jnp.where(tangent_known, d, 0.0),
                                          (trial_rate.state, trial_rate.multipliers))
        state, lam, rate = pick((trial.state, trial.multipliers, new_rate), (state, lam, rate))
        u, force = pick((u + du, trial.control_force), (u, force))
        stiffness = jnp.where(accepted, jnp.where(tangent_known,
                                                  trial_rate.control_force, 0.0), stiffness)
        increment = jnp.where(accepted, increment, 0.5 * increment)
        done = trial.converged & started & (
            jnp.abs(trial.control_force - target_force) <= tolerance)
        path = jax.tree_util.tree_map(lambda buffer, x: buffer.at[k].set(x), path, trial)
        return (k + 1, state, lam, rate, u, force, stiffness, increment, done, path)

    zero = jnp.zeros(())
    rate0 = jax.tree_util.tree_map(jnp.zeros_like, (state0, lam_start))
    start = (jnp.zeros((), int), state0, lam_start, rate0, u0, zero, zero,
             jnp.asarray(max_increment, dtype=float), jnp.zeros((), bool), empty)
    (taken, state, lam, _, _, _, _, _, reached, path) = jax.lax.while_loop(
        lambda carry: (carry[0] <= steps) & ~carry[8], step, start)
    first = jax.tree_util.tree_map(lambda x: x[0], path)
    path = jax.tree_util.tree_map(lambda x: x[1:], path)
    equilibrium = solve_load_level(structure, params, geometry, None, state, lam[:-1], solver,
                                   1.0)
    return DrivenEquilibrium(equilibrium, first, path, target, reached, taken - 1)
