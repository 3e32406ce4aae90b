"""Tension-only lines and ropes over pulleys: a smoothed ramp energy.

A line between two nodes has stretch ``l - L0`` and, exactly, the tension
``T = k (l - L0)`` when taut (``l > L0``) and ``T = 0`` when slack. Written with a kink at
``l = L0``, its energy's Hessian jumps there and Newton's method can cycle between the two
states. Here the kink is replaced, in terms of the strain ``e = (l - L0) / L0``, by a
quadratic blend over the width ``delta`` (a small strain, ``ElementParameters
.tension_smoothing``), centred on the rest length (``h = delta / 2``)::

    r(e) = 0                       for e <= -h         (slack: exactly no force)
    r(e) = (e + h)^2 / (4 h)       for -h < e < h      (the blend)
    r(e) = e                       for e >= h          (taut: exactly k (l - L0))

    T = k L0 r(e)     [N],      energy U = k L0^2 R(e) with R' = r:
    R = 0,  (e + h)^3 / (12 h),  e^2 / 2 + h^2 / 6   on the same three intervals.

``r`` is C1 (the energy C2), so the Newton Hessian is continuous through every slack-taut
change, and the tension is exact outside ``|e| < delta / 2``. Inside, the error is at most
``|r(e) - max(e, 0)| <= delta / 8`` at ``e = 0``, i.e. a tension error of at most
``k L0 delta / 8`` [N] (tested). A smooth energy was chosen over an active set because the
Newton-KKT solver, its line search and the implicit-function-theorem gradients all need one
twice-differentiable objective with fixed unknowns; an active set would add a combinatorial
outer loop and make the solution non-differentiable where a line changes state.

A rope over a pulley (frictionless, the pulley a node) is the same law on the total length
``l = |x_a - x_p| + |x_b - x_p|``: one tension on both sides.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
from jax import Array


@dataclasses.dataclass(frozen=True)
class Line:
    """A tension-only line (bridle line, canopy spring) between two nodes.

    Attributes:
        end_a, end_b: node references: a point name (:class:`PointNode`,
            :class:`FixedPoint`), ``"tube:index"``, or a global node index.
        stiffness: ``k`` [N/m]: tension ``k (l - L0)`` when taut.
        rest_length: ``L0`` [m]; ``None`` takes the reference distance of the two ends.
        name: optional label (reports, figures).
    """

    end_a: object
    end_b: object
    stiffness: float
    rest_length: float | None = None
    name: str | None = None


@dataclasses.dataclass(frozen=True)
class Pulley:
    """One rope from ``end_a`` over the pulley node ``pulley`` to ``end_b``: tension
    ``k (l1 + l2 - L0)`` when taut, the same on both sides (frictionless pulley).

    Attributes:
        end_a, pulley, end_b: node references (see :class:`Line`).
        stiffness: ``k`` [N/m] of the whole rope.
        rest_length: ``L0`` of the whole rope [m]; ``None``: the reference ``l1 + l2``.
        name: optional label.
    """

    end_a: object
    pulley: object
    end_b: object
    stiffness: float
    rest_length: float | None = None
    name: str | None = None


def _pieces(strain: Array, smoothing) -> tuple[Array, Array, Array, Array]:
    half = 0.5 * smoothing
    slack = strain <= -half
    taut = strain >= half
    blend = strain + half
    return half, slack, taut, blend


def smoothed_ramp(strain: Array, smoothing) -> Array:
    """``r(e)``: the smoothed ``max(e, 0)`` of the module docstring (dimensionless)."""
    half, slack, taut, blend = _pieces(strain, smoothing)
    inner = blend**2 / (4.0 * half)
    return jnp.where(slack, 0.0, jnp.where(taut, strain, inner))


def smoothed_ramp_integral(strain: Array, smoothing) -> Array:
    """``R(e) = int r``: the energy of the smoothed ramp per ``k L0^2`` (dimensionless)."""
    half, slack, taut, blend = _pieces(strain, smoothing)
    inner = blend**3 / (12.0 * half)
    outer = 0.5 * strain**2 + half**2 / 6.0
    return jnp.where(slack, 0.0, jnp.where(taut, outer, inner))


def tension_only_energy(length: Array, stiffness: Array, rest_length: Array,
                        smoothing) -> Array:
    """Energy ``k L0^2 R((l - L0) / L0)`` [J] of lines (or ropes) of length ``l`` [m],
    elementwise over any shape."""
    strain = (length - rest_length) / rest_length
    return stiffness * rest_length**2 * smoothed_ramp_integral(strain, smoothing)


def tension(length: Array, stiffness: Array, rest_length: Array, smoothing) -> Array:
    """Tension ``k L0 r((l - L0) / L0)`` [N] (``dU/dl``), elementwise."""
    strain = (length - rest_length) / rest_length
    return stiffness * rest_length * smoothed_ramp(strain, smoothing)


def distance(a: Array, b: Array) -> Array:
    """``|a - b|`` over the last axis [m]; ``[..., 3] -> [...]``."""
    return jnp.sqrt(jnp.sum((a - b) ** 2, axis=-1))


def line_energy(end_a: Array, end_b: Array, stiffness, rest_length, smoothing) -> Array:
    """Energy of one line (or a batch) from its end positions ``[..., 3]`` [m], in J."""
    return tension_only_energy(distance(end_a, end_b), stiffness, rest_length, smoothing)


def pulley_length(end_a: Array, pulley: Array, end_b: Array) -> Array:
    """Rope length over a pulley ``|x_a - x_p| + |x_b - x_p|`` [m]."""
    return distance(end_a, pulley) + distance(end_b, pulley)


def pulley_energy(end_a: Array, pulley: Array, end_b: Array, stiffness, rest_length,
                  smoothing) -> Array:
    """Energy of one rope over a pulley (or a batch), in J."""
    return tension_only_energy(pulley_length(end_a, pulley, end_b), stiffness, rest_length,
                               smoothing)
