"""Rotation maps and the joint energy are smooth at zero rotation (value, gradient, Hessian)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxtube as jt
from jaxtube._rotation import (
    inverse_right_jacobian_transpose,
    minimal_rotation,
    right_jacobian,
    skew,
)


def _rodrigues_reference(theta):
    t = np.linalg.norm(theta)
    if t == 0:
        return np.eye(3)
    k = skew(jnp.asarray(theta / t))
    return np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * (k @ k)


@pytest.mark.parametrize("scale", [0.0, 1e-9, 1e-3, 0.3, 2.0, 3.0])
def test_exp_log_round_trip(scale):
    rng = np.random.default_rng(0)
    theta = rng.normal(size=3)
    theta = scale * theta / np.linalg.norm(theta)
    rot = jt.rotation_matrix(jnp.asarray(theta))
    np.testing.assert_allclose(rot, _rodrigues_reference(theta), atol=1e-14)
    np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-14)
    np.testing.assert_allclose(jt.rotation_vector(rot), theta, atol=1e-12)


def test_exp_map_derivatives_at_zero():
    weights = jnp.arange(9.0).reshape(3, 3) - 4.0

    @jax.jit
    def scalar(theta):
        return jnp.sum(weights * jt.rotation_matrix(theta))

    grad = jax.grad(scalar)(jnp.zeros(3))
    hess = jax.hessian(scalar)(jnp.zeros(3))
    # R = I + [t]x + [t]x^2 / 2 + O(t^3): gradient from [t]x, Hessian from [t]x^2 / 2.
    w = np.asarray(weights)
    expected_grad = np.array([w[2, 1] - w[1, 2], w[0, 2] - w[2, 0], w[1, 0] - w[0, 1]])
    np.testing.assert_allclose(grad, expected_grad, atol=1e-14)
    eps = 1e-4
    fd = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            ei, ej = np.eye(3)[i] * eps, np.eye(3)[j] * eps
            fd[i, j] = (scalar(ei + ej) - scalar(ei - ej) - scalar(-ei + ej) + scalar(-ei - ej)) / (
                4 * eps * eps
            )
    assert np.all(np.isfinite(hess))
    np.testing.assert_allclose(hess, fd, atol=1e-7)


def test_log_map_derivatives_at_identity():
    jac = jax.jit(jax.jacfwd(lambda t: jt.rotation_vector(jt.rotation_matrix(t))))(jnp.zeros(3))
    np.testing.assert_allclose(jac, np.eye(3), atol=1e-14)
    hess = jax.hessian(lambda t: jnp.sum(jt.rotation_vector(jt.rotation_matrix(t)) ** 2))(
        jnp.zeros(3)
    )
    np.testing.assert_allclose(hess, 2 * np.eye(3), atol=1e-12)


def test_minimal_rotation_maps_vectors():
    a = jnp.array([1.0, 0.0, 0.0])
    b = jnp.array([0.6, 0.8, 0.0])
    rot = minimal_rotation(a, b)
    np.testing.assert_allclose(rot @ a, b, atol=1e-15)
    np.testing.assert_allclose(rot @ np.array([0, 0, 1.0]), [0, 0, 1.0], atol=1e-15)


def test_inverse_right_jacobian_matches_finite_differences():
    theta = jnp.array([0.3, -0.5, 0.2])
    # exp(theta + d) = exp(theta) exp(J_r d)  =>  J_r = d/dd log(exp(theta)^T exp(theta + d)).
    jr = jax.jacfwd(
        lambda d: jt.rotation_vector(jt.rotation_matrix(theta).T @ jt.rotation_matrix(theta + d))
    )(jnp.zeros(3))
    np.testing.assert_allclose(inverse_right_jacobian_transpose(theta), np.linalg.inv(jr).T,
                               atol=1e-12)



@pytest.mark.parametrize("scale", [0.0, 1e-5, 5e-3, 0.3, 2.5])
def test_right_jacobian_and_its_derivative(scale):
    """``J_r`` is the derivative of ``d -> log(exp(theta)^T exp(theta + d))`` at 0, across its
    Taylor branch and the closed form (``t^2`` below and above 1e-4), and so is its
    forward-mode derivative (what the joints' Hessian blocks use); at zero, ``J_r = I``
    and ``dJ_r/dtheta_k = -[e_k]x / 2``."""
    direction = jnp.array([0.3, -0.5, 0.2]) / np.sqrt(0.38)

    def reference(theta):
        return jax.jacfwd(lambda d: jt.rotation_vector(
            jt.rotation_matrix(theta).T @ jt.rotation_matrix(theta + d)))(jnp.zeros(3))

    theta = scale * direction
    np.testing.assert_allclose(right_jacobian(theta), reference(theta), atol=1e-13)
    # J_r(-theta) = J_r(theta)^T (the left Jacobian).
    np.testing.assert_allclose(right_jacobian(-theta), right_jacobian(theta).T, atol=1e-15)
    tangent = jnp.array([0.7, 0.1, -0.4])
    derivative = jax.jvp(right_jacobian, (theta,), (tangent,))[1]
    assert np.all(np.isfinite(derivative))
    if scale == 0.0:
        np.testing.assert_allclose(derivative, -0.5 * skew(tangent), atol=1e-15)
    else:
        step = 1e-6 * max(scale, 1.0)
        finite = (right_jacobian(theta + step * tangent)
                  - right_jacobian(theta - step * tangent)) / (2 * step)
        np.testing.assert_allclose(derivative, finite, atol=1e-8)


def test_joint_energy_gradient_and_hessian_at_zero_rotation():
    """Energy of a one-segment cantilever: clamp joint, tributary L/2. At zero rotation the
    gradient is zero and the Hessian is diag(EI, EI, GJ) / (L/2), for every law."""
    length, bend, twist = 0.4, 7.0, 5.0
    laws = [
        (jt.LinearLaw(bend), jt.LinearLaw(twist), bend, twist),
        (jt.TensionFieldLaw(150e3), jt.LinearLaw(twist), None, twist),
        (jt.SplineLaw.from_tension_field(150e3, 2e4, 0.075), jt.EmpiricalTorsionLaw2011(),
         None, None),
    ]
    for bending_law, torsion_law, ei, gj in laws:
        structure, params = jt.cantilever(length, 0.075, 2e4, 1, bending_law, torsion_law)
        geometry = jt.reference_geometry(structure, params)
        if ei is None:
            ei = float(bending_law.initial_stiffness(2e4, 0.075))
        if gj is None:
            gj = float(torsion_law.initial_stiffness(2e4, 0.075))

        def energy(theta):
            state = {"root_position": params.node_position[0], "segment_rotation": theta[None]}
            return jt.total_energy(structure, params, geometry, state)

        zero = jnp.zeros(3)
        grad = jax.jit(jax.grad(energy))(zero)
        hess = jax.jit(jax.hessian(energy))(zero)
        assert np.all(np.isfinite(grad)) and np.all(np.isfinite(hess))
        np.testing.assert_allclose(grad, 0.0, atol=1e-12)
        expected = np.diag([ei, ei, gj]) / (0.5 * length)
        np.testing.assert_allclose(hess, expected, rtol=1e-9, atol=1e-9 * ei)
