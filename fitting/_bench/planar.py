"""Planar statics of the tip-loaded rigid-segment cantilever: the sweep's exact fast path.

The discrete model is jaxtube's rigid-segment chain of the standard bench cantilever
(:class:`fitting.CantileverRig` without rig features; ``jaxtube._mechanics``): ``n`` rigid
segments of length ``h = L / n`` along +x, spherical spring joints ``k = 1..n`` at nodes
``x_k = (k - 1) h``. Joint 1 is the clamp (ground to segment 1), with tributary length
``l_1 = h / 2``; the internal joints have ``l_k = h`` (``reference_geometry``: half the
segment length against the ground, the mean of the two segment lengths between segments).
A joint of rotation ``theta_k`` has curvature ``kappa_k = theta_k / l_k`` and energy
``l_k W(kappa_k^2)``, so ``dE/dtheta_k = M(kappa_k)``, the law's moment (docs/physics.md,
section 1.2).

A dead vertical tip load ``F`` (along -z) keeps the chain in the x-z plane. With the
absolute segment angles ``phi_j = theta_1 + ... + theta_j`` (rotation about +y, so a
positive angle turns +x towards -z) the potential is
``Pi = sum_k l_k W(kappa_k^2) - F sum_j h sin(phi_j)``, and stationarity in ``theta_k`` is
the statics of a cut at joint ``k`` (the structure is statically determinate)::

    M(kappa_k) = F a_k,      a_k = sum_{j >= k} h cos(phi_j)                    (1)

``a_k`` [m] is the lever arm: the horizontal distance from joint ``k``'s node to the tip.
The tip deflection is ``v = sum_j h sin(phi_j)``. In the planar case the joint rotation
vector is exactly ``theta_k e_y`` (``H_pre = H_post = I`` for a straight tube, and
rotations about one axis compose by adding angles), and the moment transmitted through the
finite rotation, ``J_r(theta)^-T M``, equals ``M`` because ``J_r(theta) theta = theta``.
So (1) is the generic 3-D equilibrium of the same chain, not an approximation of it (the
sweep's tests check it against ``jaxtube.equilibrium``).

Where ``0 <= phi_j <= pi / 2`` the energy is strictly convex in ``theta``: its Hessian is
``diag(M'(kappa_k) / l_k) + F sum_j h sin(phi_j) s_j s_j^T`` with ``s_j`` the indicator of
joints ``1..j``, positive definite for a monotone law. So (1) has at most one solution
there, the stable equilibrium; a dead downward tip load never turns a segment past the
vertical. The solves keep their iterates in that region.

Two problems, each solved by Newton steps on the residual of (1) scaled by a reference
moment, until its largest entry is at most ``tolerance`` (or not finite), at most ``steps``
of them (a ``lax.while_loop``). Under ``vmap`` that loop runs until the slowest point of
the chunk has converged, with the converged points frozen (the batched loop selects their
old state), so a point's result does not depend on its chunk and no chunk does more work
than a fixed ``steps``-step loop would; a chunk of easy points stops early. The Jacobian
is exact: the law's slopes ``M'(kappa_k)`` by one ``jax.jvp``
(the law is elementwise) and the lever arms' derivatives in closed form,
``da_k/dtheta_m = -sum_{j >= max(k, m)} h sin(phi_j)`` (a test checks it against
``jax.jacfwd``); the step by ``jnp.linalg.solve``.

- :func:`deflection_at_load`: the equilibrium at a given load ``F``; unknowns
  ``theta_1..theta_n`` (the Jacobian is the energy's Hessian); from the linear
  small-deflection shape ``kappa = F (L - x) / EI0``, scaled down to a tip angle of at most
  :data:`START_TIP_ANGLE`.
- :func:`load_at_root_curvature`: the load at which the root joint has a given curvature
  ``kappa_1`` (the law's wrinkling or collapse curvature): ``theta_1 = kappa_1 l_1`` is
  known; unknowns ``F`` and ``theta_2..theta_n``; the root equation of (1) reads
  ``M(kappa_1) = F a_1``. Every other joint carries less moment (``a_k < a_1``), so
  ``0 <= kappa_k <= kappa_1`` (a monotone law), and ``F >= M(kappa_1) / L`` (``a_1 <= L``):
  the iterates are kept in these bounds. A root rotation ``kappa_1 l_1 >= pi / 2`` cannot
  be reached at all (``reachable``). Start: ``F = M(kappa_1) / L`` and the linear shape,
  each curvature capped at ``kappa_1``.

Safeguards of each step (no line search, which would cost law evaluations): the Newton
step is scaled so that no joint rotation changes by more than :data:`MAX_ROTATION_STEP`
(a trust region in the rotations: the moment of a tension-field law flattens towards
``M_c``, where undamped Newton steps in the curvature overshoot); the trial point is
projected on the bounds; if the tip angle ``phi_n`` would pass ``pi / 2``, the rotations
go only 90 % of the way to it (a convex combination of two feasible points stays
feasible), while the load of a load problem keeps its whole step (holding it back as well
stalls the iteration against the bound: the 2011 law at small radii, where the tube hangs
almost vertically before its root wrinkles). With these, the largest number of steps that
any point needed over 0.1-0.5 bar, r = 30-150 mm, L = 0.5-2 m, tip loads 0.1-500 N and
the tension-field (E t = 150 kN/m and 5 MN/m), spline and 2011 laws was 5 (wrinkling), 7
(collapse) and 14 (deflection), out of 20,000 random specimens per law (a larger step cap,
1 rad, made 1-10 % of the deflections cycle).

Convergence is reported, never assumed: at the returned state, the residual of (1) (the
largest ``|M(kappa_k) - F a_k|`` over the unknown joints, relative to the reference moment)
must be at most ``tolerance``; the root equation of a load problem is reported apart, as
the relative mismatch ``|F a_1 / M(kappa_1) - 1|``. Result codes are those of
``jaxtube.RESULT_MESSAGES`` (0 converged, 1 not converged in the steps, 3 non-finite).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array

import jaxtube as jt

from .._codes import code

RESULT_CONVERGED = code(jt.RESULTS.successful)
RESULT_NOT_CONVERGED = code(jt.RESULTS.max_steps_reached)
RESULT_NON_FINITE = code(jt.RESULTS.nonfinite)

#: Largest change of one joint rotation in one Newton step [rad].
MAX_ROTATION_STEP = 0.5
#: Tip angle of the linear starting shape, at most [rad].
START_TIP_ANGLE = 1.0
#: Fraction of the room between the root rotation and a vertical tip that the starting
#: shape of a load problem uses, at most.
START_ROOM_FRACTION = 0.5
#: Fraction of the way to the vertical tip (``phi_n = pi / 2``) that a step may go.
_TO_BOUNDARY = 0.9


class PlanarEquilibrium(eqx.Module):
    """One planar equilibrium of the tip-loaded chain (scalars unless noted).

    Attributes:
        load: dead tip load ``F`` [N] (given, or found).
        joint_rotation: ``theta_k`` [rad], shape ``[n]`` (joint 1 is the clamp).
        tip_deflection: downward tip displacement ``sum_j h sin(phi_j)`` [m].
        residual: largest ``|M(kappa_k) - F a_k|`` of the unknown joints over the reference
            moment, at the returned state.
        root_mismatch: ``|F a_1 / M(kappa_1) - 1|`` of a load problem (0 for a deflection).
        reachable: False where a load problem's root rotation ``kappa_1 l_1`` is at least
            ``pi / 2``: no equilibrium under a downward tip load has that root curvature
            (True for a deflection).
        result: 0 converged, 1 not converged within ``steps``, 3 non-finite (int32).
        steps: Newton steps taken (int32).
    """

    load: Array
    joint_rotation: Array
    tip_deflection: Array
    residual: Array
    root_mismatch: Array
    reachable: Array
    result: Array
    steps: Array


def tributary_lengths(length, segments: int) -> Array:
    """``l_k`` [m], shape ``[n]``: ``h / 2`` at the clamp, ``h`` at the internal joints
    (``h = length / segments``; ``jaxtube._mechanics.reference_geometry``)."""
    h = jnp.asarray(length, float) / segments
    return h * jnp.concatenate([jnp.full((1,), 0.5), jnp.ones(segments - 1)])


def _from_tip(values: Array) -> Array:
    """``out_k = sum_{j >= k} values_j``."""
    return jnp.cumsum(values[::-1])[::-1]


def lever_arms(joint_rotation: Array, segment_length) -> tuple[Array, Array]:
    """Lever arms ``a_k = sum_{j >= k} h cos(phi_j)`` [m], shape ``[n]``, and the tip
    deflection ``sum_j h sin(phi_j)`` [m], for joint rotations ``[n]`` [rad] (eq. (1))."""
    angle = jnp.cumsum(joint_rotation)
    return (_from_tip(segment_length * jnp.cos(angle)),
            jnp.sum(segment_length * jnp.sin(angle)))


class _Chain(NamedTuple):
    """Statics of one shape: eq. (1)'s terms and their derivatives in the rotations."""

    moment: Array  # M(kappa_k) [N m], [n]
    moment_slope: Array  # dM(kappa_k)/dtheta_k = M'(kappa_k) / l_k [N m], [n]
    arm: Array  # a_k [m], [n]
    arm_slope: Array  # -da_k/dtheta_m = sum_{j >= max(k, m)} h sin(phi_j) [m], [n, n]


def _chain(law, pressure, radius, tributary, segment_length, rotation) -> _Chain:
    """Law moments with their slopes (one ``jax.jvp``: the law is elementwise) and the
    lever arms with their exact derivatives (``da_k/dtheta_m = -sum_{j >= max(k, m)} h
    sin(phi_j)``, as ``phi_j`` depends on ``theta_m`` for ``m <= j``)."""
    moment, slope = jax.jvp(lambda t: law.moment(t / tributary, pressure, radius),
                            (rotation,), (jnp.ones_like(rotation),))
    angle = jnp.cumsum(rotation)
    arm = _from_tip(segment_length * jnp.cos(angle))
    sine_sum = _from_tip(segment_length * jnp.sin(angle))
    count = rotation.shape[0]
    later = jnp.maximum(jnp.arange(count)[:, None], jnp.arange(count)[None, :])
    return _Chain(moment, slope, arm, sine_sum[later])


def _newton(linearised, start: Array, rotations, upper: Array, lower: Array,
            load_first: bool, steps: int, tolerance: float):
    """Safeguarded Newton steps on ``residual(x) = 0`` from ``start`` (the safeguards of the
    module docstring), until the largest residual is at most ``tolerance`` or not finite,
    at most ``steps`` of them.

    ``linearised(x)`` gives ``(residual [m], Jacobian [m, m])``; ``rotations(x)`` all joint
    rotations ``[n]`` [rad], affine in ``x``; ``lower``/``upper`` bound ``x``;
    ``load_first``: ``x[0]`` is a load, which takes its whole (bounded) step when the
    rotations are held back from the vertical tip (holding it back too stalls the iteration
    against that bound). Returns the final state, its residual and the steps taken.
    """
    offset = rotations(jnp.zeros_like(start))

    def unfinished(state):
        taken, _, value, _ = state
        return (taken < steps) & (jnp.max(jnp.abs(value)) > tolerance)

    def step(state):
        taken, x, value, jacobian = state
        direction = -jnp.linalg.solve(jacobian, value)
        change = jnp.max(jnp.abs(rotations(direction) - offset))
        scale = jnp.minimum(1.0, MAX_ROTATION_STEP / jnp.where(change > 0, change, 1.0))
        trial = jnp.clip(x + scale * direction, lower, upper)
        tip, tip_trial = jnp.sum(rotations(x)), jnp.sum(rotations(trial))
        rise = tip_trial - tip
        fraction = jnp.where(tip_trial > 0.5 * math.pi,
                             _TO_BOUNDARY * (0.5 * math.pi - tip)
                             / jnp.where(rise > 0, rise, 1.0), 1.0)
        fraction = jnp.clip(fraction, 0.0, 1.0)
        if load_first:
            fraction = jnp.concatenate([jnp.ones(1), jnp.full(x.shape[0] - 1, fraction)])
        x = x + fraction * (trial - x)
        return (taken + 1, x) + linearised(x)

    state = (jnp.zeros((), jnp.int32), start) + linearised(start)
    taken, x, value, _ = jax.lax.while_loop(unfinished, step, state)
    return x, value, taken


def _result_code(residual_norm: Array, tolerance: float) -> Array:
    return jnp.where(~jnp.isfinite(residual_norm), RESULT_NON_FINITE,
                     jnp.where(residual_norm <= tolerance, RESULT_CONVERGED,
                               RESULT_NOT_CONVERGED)).astype(jnp.int32)


def deflection_residual(law: jt.AbstractMomentLaw, pressure, radius, length, load,
                        rotation: Array) -> tuple[Array, Array]:
    """Residual ``(M(kappa_k) - F a_k) / (F L)`` of eq. (1), shape ``[n]``, at the joint
    rotations ``rotation [n]`` [rad] under the tip load ``load`` [N] (``/ 1`` at zero load),
    and its exact Jacobian ``[n, n]`` with respect to the rotations: the energy's Hessian
    ``(diag(M'(kappa_k) / l_k) + F sum_{j >= max(k, m)} h sin(phi_j)) / (F L)``."""
    segments = rotation.shape[0]
    h = length / segments
    scale = jnp.where(load * length > 0, load * length, 1.0)
    chain = _chain(law, pressure, radius, tributary_lengths(length, segments), h, rotation)
    value = (chain.moment - load * chain.arm) / scale
    return value, (jnp.diag(chain.moment_slope) + load * chain.arm_slope) / scale


def _load_rotations(root_curvature, length, x: Array) -> Array:
    """All joint rotations [rad] of a load problem's unknowns ``x = (F / F_0, theta_2..)``."""
    root_rotation = root_curvature * tributary_lengths(length, x.shape[0])[0]
    return jnp.where(jnp.arange(x.shape[0]) == 0, root_rotation, x)


def load_residual(law: jt.AbstractMomentLaw, pressure, radius, length, root_curvature,
                  x: Array) -> tuple[Array, Array]:
    """Residual of eq. (1) with the root curvature given, shape ``[n]``, and its exact
    Jacobian ``[n, n]``, at ``x = (F / F_0, theta_2..theta_n)`` (``F_0 = M_t / L``,
    ``M_t = M(root_curvature)``): ``(M_t - F a_1) / M_t`` at the root and
    ``(M(kappa_k) - F a_k) / M_t`` at the other joints. Column 0 of the Jacobian is
    ``-F_0 a_k / M_t``; the others as in :func:`deflection_residual`, without the root's
    law term (its curvature is fixed)."""
    segments = x.shape[0]
    h = length / segments
    is_root = jnp.arange(segments) == 0
    target = law.moment(root_curvature, pressure, radius)
    reference_load = target / length
    load = x[0] * reference_load
    chain = _chain(law, pressure, radius, tributary_lengths(length, segments), h,
                   _load_rotations(root_curvature, length, x))
    value = (jnp.where(is_root, target, chain.moment) - load * chain.arm) / target
    jacobian = jnp.diag(jnp.where(is_root, 0.0, chain.moment_slope)) + load * chain.arm_slope
    jacobian = jnp.where(is_root[None, :], -reference_load * chain.arm[:, None], jacobian)
    return value, jacobian / target


def deflection_at_load(law: jt.AbstractMomentLaw, pressure, radius, length, load,
                       segments: int, steps: int, tolerance: float) -> PlanarEquilibrium:
    """Equilibrium of the cantilever under the dead tip load ``load`` [N] (>= 0), by
    ``steps`` Newton steps on :func:`deflection_residual` (converged where its largest
    entry is at most ``tolerance``).

    Scalars in (``pressure`` [Pa], ``radius`` [m], ``length`` [m]); traceable. Start: the
    linear shape ``kappa = F (L - x) / EI0``, scaled down to a tip angle of at most
    :data:`START_TIP_ANGLE`.
    """
    load = jnp.asarray(load, float)
    tributary = tributary_lengths(length, segments)
    node_x = length / segments * jnp.arange(segments, dtype=float)
    linear = load * (length - node_x) * tributary / law.initial_stiffness(pressure, radius)
    tip = jnp.sum(linear)
    start = linear * jnp.minimum(1.0, START_TIP_ANGLE / jnp.where(tip > 0, tip, 1.0))
    start = jnp.where(jnp.isfinite(start) & (start >= 0), start, 0.0)
    rotation, value, used = _newton(
        lambda x: deflection_residual(law, pressure, radius, length, load, x), start,
        lambda x: x, jnp.full(segments, jnp.inf), jnp.zeros(segments), False, steps,
        tolerance)
    norm = jnp.max(jnp.abs(value))
    _, deflection = lever_arms(rotation, length / segments)
    return PlanarEquilibrium(load=load, joint_rotation=rotation, tip_deflection=deflection,
                             residual=norm, root_mismatch=jnp.zeros_like(norm),
                             reachable=jnp.ones((), bool),
                             result=_result_code(norm, tolerance), steps=used)


def load_at_root_curvature(law: jt.AbstractMomentLaw, pressure, radius, length,
                           root_curvature, segments: int, steps: int,
                           tolerance: float) -> PlanarEquilibrium:
    """The dead tip load [N] at which the clamp joint has curvature ``root_curvature``
    [1/m] (> 0), i.e. carries the moment ``M_t = M(root_curvature)``, by ``steps`` Newton
    steps on :func:`load_residual`.

    Scalars in; traceable. Converged where the largest residual of the joints ``2..n`` is
    at most ``tolerance``; the root's residual is reported as ``root_mismatch``. Bounds:
    ``F / F_0 >= 1`` (``a_1 <= L``) and ``0 <= kappa_k <= kappa_1`` (``a_k < a_1`` and a
    monotone law). Start: ``F = F_0`` and the linear shape, each curvature capped at
    ``kappa_1``, the joints ``2..n`` scaled to turn the tip by at most
    :data:`START_ROOM_FRACTION` of the room left to the vertical.
    """
    tributary = tributary_lengths(length, segments)
    is_root = jnp.arange(segments) == 0
    root_rotation = root_curvature * tributary[0]
    target = law.moment(root_curvature, pressure, radius)
    node_x = length / segments * jnp.arange(segments, dtype=float)
    linear = jnp.minimum(target * (length - node_x) / length
                         / law.initial_stiffness(pressure, radius), root_curvature)
    chain = jnp.where(is_root, 0.0, linear * tributary)
    chain = jnp.where(jnp.isfinite(chain) & (chain >= 0), chain, 0.0)
    room = START_ROOM_FRACTION * (0.5 * math.pi - root_rotation)
    total = jnp.sum(chain)
    chain = chain * jnp.clip(room / jnp.where(total > 0, total, 1.0), 0.0, 1.0)
    x, value, used = _newton(
        lambda x: load_residual(law, pressure, radius, length, root_curvature, x),
        jnp.where(is_root, 1.0, chain),
        lambda x: _load_rotations(root_curvature, length, x),
        jnp.where(is_root, jnp.inf, root_curvature * tributary), jnp.where(is_root, 1.0, 0.0),
        True, steps, tolerance)
    norm = jnp.max(jnp.abs(jnp.where(is_root, 0.0, value)))
    rotation = _load_rotations(root_curvature, length, x)
    _, deflection = lever_arms(rotation, length / segments)
    return PlanarEquilibrium(load=x[0] * target / length, joint_rotation=rotation,
                             tip_deflection=deflection, residual=norm,
                             root_mismatch=jnp.abs(value[0]),
                             reachable=root_rotation < 0.5 * math.pi,
                             result=_result_code(norm, tolerance), steps=used)
