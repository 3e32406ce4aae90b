"""Rotation helpers that stay smooth (value, gradient and Hessian) at zero rotation.

Rotation vectors ``theta`` (shape ``[..., 3]``, radians) map to rotation matrices by the
exponential map (Rodrigues' formula)::

    R = I + a(t) [theta]x + b(t) [theta]x^2,   a = sin t / t,   b = (1 - cos t) / t^2,

with ``t^2 = theta . theta``. Written the obvious way (``t = |theta|``) both coefficients are
0/0 at zero and their derivatives are NaN. Here ``a`` and ``b`` are evaluated as functions
of ``t^2`` with a Taylor branch below a threshold and the ``jnp.where`` double-guard above
it, so that forward- and reverse-mode derivatives of any order are finite and exact at
zero. The logarithm uses the same device.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import Array

# Below this t^2 the Taylor series (to t^6) are exact to float64 round-off.
_SMALL_ANGLE_SQ = 1e-4


def matmul3(a: Array, b: Array) -> Array:
    """Batched 3x3 product ``a @ b`` written elementwise: XLA on CPU runs batches of tiny
    ``dot_general`` calls far slower than this fused multiply-add; ``[...,3,3]``."""
    return jnp.sum(a[..., :, :, None] * b[..., None, :, :], axis=-2)


def matvec3(a: Array, v: Array) -> Array:
    """Batched ``a @ v`` for ``a [..., 3, 3]`` and ``v [..., 3]``, written elementwise."""
    return jnp.sum(a * v[..., None, :], axis=-1)


def transpose3(a: Array) -> Array:
    """Swap the last two axes."""
    return jnp.swapaxes(a, -1, -2)


def skew(vector: Array) -> Array:
    """Cross-product matrix ``[v]x`` with ``[v]x w = v x w``; shape ``[..., 3] -> [..., 3, 3]``."""
    x, y, z = vector[..., 0], vector[..., 1], vector[..., 2]
    zero = jnp.zeros_like(x)
    return jnp.stack(
        [
            jnp.stack([zero, -z, y], axis=-1),
            jnp.stack([z, zero, -x], axis=-1),
            jnp.stack([-y, x, zero], axis=-1),
        ],
        axis=-2,
    )


def _rodrigues_coefficients(angle_sq: Array) -> tuple[Array, Array]:
    """``a = sin t / t`` and ``b = (1 - cos t) / t^2`` as smooth functions of ``t^2``."""
    small = angle_sq < _SMALL_ANGLE_SQ
    safe_sq = jnp.where(small, 1.0, angle_sq)
    angle = jnp.sqrt(safe_sq)
    a_large = jnp.sin(angle) / angle
    b_large = (1.0 - jnp.cos(angle)) / safe_sq
    s = angle_sq
    a_small = 1.0 - s / 6.0 + s * s / 120.0 - s * s * s / 5040.0
    b_small = 0.5 - s / 24.0 + s * s / 720.0 - s * s * s / 40320.0
    return jnp.where(small, a_small, a_large), jnp.where(small, b_small, b_large)


@jax.jit
def rotation_matrix(rotation_vector: Array) -> Array:
    """Exponential map ``so(3) -> SO(3)``; ``[..., 3] -> [..., 3, 3]`` (Rodrigues' formula)."""
    angle_sq = jnp.sum(rotation_vector * rotation_vector, axis=-1)
    a, b = _rodrigues_coefficients(angle_sq)
    # [t]x^2 = t t^T - |t|^2 I: no matrix product needed.
    outer = rotation_vector[..., :, None] * rotation_vector[..., None, :]
    eye = jnp.eye(3, dtype=rotation_vector.dtype)
    return ((1.0 - b * angle_sq)[..., None, None] * eye + a[..., None, None] *
            skew(rotation_vector) + b[..., None, None] * outer)


@jax.jit
def rotation_vector(rotation: Array) -> Array:
    """Logarithm ``SO(3) -> so(3)`` for rotation angles below pi; ``[..., 3, 3] -> [..., 3]``.

    With ``w = vee(R - R^T) / 2 = sin t n`` and ``cos t = (tr R - 1) / 2`` the rotation
    vector is ``t / sin t * w``. For small ``|w|^2 = sin^2 t`` the factor is the series of
    ``arcsin(x) / x`` in ``x^2`` (valid while ``cos t > 0``), so derivatives stay exact at
    the identity. Angles near pi are not needed by the model (they would mean a joint
    folded back on itself) and are not handled specially.
    """
    w = 0.5 * jnp.stack(
        [
            rotation[..., 2, 1] - rotation[..., 1, 2],
            rotation[..., 0, 2] - rotation[..., 2, 0],
            rotation[..., 1, 0] - rotation[..., 0, 1],
        ],
        axis=-1,
    )
    cos_angle = 0.5 * (jnp.trace(rotation, axis1=-2, axis2=-1) - 1.0)
    sin_sq = jnp.sum(w * w, axis=-1)
    small = (sin_sq < _SMALL_ANGLE_SQ) & (cos_angle > 0.0)
    safe_sin_sq = jnp.where(small, 1.0, sin_sq)
    sin_angle = jnp.sqrt(safe_sin_sq)
    factor_large = jnp.arctan2(sin_angle, cos_angle) / sin_angle
    x = sin_sq
    factor_small = 1.0 + x / 6.0 + 3.0 * x * x / 40.0 + 5.0 * x * x * x / 112.0
    factor = jnp.where(small, factor_small, factor_large)
    return factor[..., None] * w


def minimal_rotation(from_unit: Array, to_unit: Array) -> Array:
    """Smallest rotation taking unit vector ``from_unit`` to ``to_unit``; ``[...,3] -> [...,3,3]``.

    ``R = I + [v]x + [v]x^2 / (1 + c)`` with ``v = a x b`` and ``c = a . b`` (smooth except
    for antiparallel vectors, which a tube's neighbouring segments never are).
    """
    v = jnp.cross(from_unit, to_unit)
    c = jnp.sum(from_unit * to_unit, axis=-1)
    k = skew(v)
    eye = jnp.eye(3, dtype=from_unit.dtype)
    return eye + k + matmul3(k, k) / (1.0 + c)[..., None, None]


def inverse_right_jacobian_transpose(rotation_vector_: Array) -> Array:
    """``J_r(theta)^{-T}``: maps the energy gradient ``dW/dtheta`` to the physical moment.

    With ``exp(theta + d) = exp(theta) exp(J_r d)``, a body rotation ``dphi = J_r dtheta``
    does work ``m . dtheta = M . dphi``, so ``M = J_r^{-T} m``. ``J_r^{-1} = I + [t]x / 2 +
    c [t]x^2`` with ``c = 1/t^2 - (1 + cos t) / (2 t sin t)`` (series ``1/12 + t^2/720 +
    t^4/30240`` near zero). Shapes ``[..., 3] -> [..., 3, 3]``.
    """
    angle_sq = jnp.sum(rotation_vector_ * rotation_vector_, axis=-1)
    small = angle_sq < _SMALL_ANGLE_SQ
    safe_sq = jnp.where(small, 1.0, angle_sq)
    angle = jnp.sqrt(safe_sq)
    c_large = 1.0 / safe_sq - (1.0 + jnp.cos(angle)) / (2.0 * angle * jnp.sin(angle))
    c_small = 1.0 / 12.0 + angle_sq / 720.0 + angle_sq * angle_sq / 30240.0
    c = jnp.where(small, c_small, c_large)
    k = skew(rotation_vector_)
    eye = jnp.eye(3, dtype=rotation_vector_.dtype)
    return eye - 0.5 * k + c[..., None, None] * matmul3(k, k)


def right_jacobian(rotation_vector_: Array) -> Array:
    """``J_r(theta)``: ``exp(theta + d) = exp(theta) exp(J_r(theta) d)`` to first order in
    ``d``. ``J_r = I - b [t]x + c [t]x^2`` with ``b = (1 - cos t) / t^2`` and ``c = (t - sin
    t) / t^3`` (series ``1/2 - t^2/24 + ...`` and ``1/6 - t^2/120 + ...`` near zero, so
    derivatives of every order stay exact there); ``J_r(-theta) = J_r(theta)^T`` is the left
    Jacobian. Shapes ``[..., 3] -> [..., 3, 3]``. (Sola, Deray & Atchuthan, "A micro Lie
    theory for state estimation in robotics", arXiv:1812.01537, 2018, the SO(3) right
    Jacobian; ``docs/physics.md`` section 1.5.)
    """
    angle_sq = jnp.sum(rotation_vector_ * rotation_vector_, axis=-1)
    _, b = _rodrigues_coefficients(angle_sq)  # the exponential map's (1 - cos t) / t^2
    small = angle_sq < _SMALL_ANGLE_SQ
    safe_sq = jnp.where(small, 1.0, angle_sq)
    angle = jnp.sqrt(safe_sq)
    s = angle_sq
    c = jnp.where(small, 1.0 / 6.0 - s / 120.0 + s * s / 5040.0 - s * s * s / 362880.0,
                  (angle - jnp.sin(angle)) / (safe_sq * angle))
    k = skew(rotation_vector_)
    eye = jnp.eye(3, dtype=rotation_vector_.dtype)
    return eye - b[..., None, None] * k + c[..., None, None] * matmul3(k, k)
