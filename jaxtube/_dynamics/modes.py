"""Natural modes at an equilibrium: the constrained generalised eigenproblem.

At an equilibrium ``(z*, lambda*)`` of the solver's state the small motions obey
``M dz'' + K dz = 0`` on the constraints' tangent space ``J dz = 0``, where

- ``K`` is the Hessian of the Lagrangian ``E + lambda* . c``: the joints' tangent
  stiffness, the lines' (with the geometric stiffness of their tension), and the geometric
  stiffness of the dead loads and of the support reactions (the multiplier terms);
- ``M`` is the mass matrix of the same coordinates (:func:`jaxtube._dynamics.inertia
  .mass_matrix`);
- ``J`` is the constraint Jacobian.

With ``Z`` a basis of the null space of ``J`` the reduced problem
``Z^T K Z y = omega^2 Z^T M Z y`` is solved by a Cholesky factor ``L`` of ``Z^T M Z`` and
the symmetric eigenproblem of ``L^{-1} Z^T K Z L^{-T}`` (``jnp.linalg.eigh``). ``Z``
eliminates ``m`` independent columns of ``J`` (chosen by an LU factorisation of ``J^T``
with partial pivoting, the choice's derivative stopped): ``Z = P [-J_B^{-1} J_F; I]``
follows ``J`` differentiably, and the eigenvalues depend only on its span, so frequencies
are differentiable in every parameter (for distinct eigenvalues) through the equilibrium's
own implicit derivative. (An orthonormal basis from an SVD of ``J`` gave the same span at
20 times the cost on the V3 kite: 10 s of a 12 s analysis.) The constraints must be
independent (full row rank ``J``); every free unknown must carry mass.

Modes whose ``omega^2`` is below ``zero_tolerance`` times the largest are *zero-frequency*
modes: rigid-body motions of a free structure, or mechanisms (a free spherical joint, a
slack line). A negative ``omega^2`` beyond it means the equilibrium is unstable.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array
from jax.flatten_util import ravel_pytree

from .._elements import dense_from_blocks
from .._equilibrium import Solution, tube_reference_geometry
from .._mechanics.energy import constraints, tube_configuration
from .._mechanics.hessian import lagrangian_hessian_blocks
from .._structure.structure import Structure, StructureParameters
from .inertia import mass_matrix


class Modes(eqx.Module):
    """Natural modes of an equilibrium, lowest first (``k`` modes, ``n`` state unknowns).

    Attributes:
        eigenvalue: ``omega^2`` ``[k]`` [rad^2/s^2] (negative: unstable).
        angular_frequency: ``sqrt(max(omega^2, 0))`` ``[k]`` [rad/s].
        frequency: ``[k]`` [Hz].
        shape: mass-normalised mode shapes in the flattened state ``[k, n]``
            (``shape M shape^T = I``).
        node_displacement: the nodes' motion per unit modal coordinate ``[k, N + P0, 3]``
            (tube nodes, then point nodes, as ``Solution.node_position``).
        zero_frequency: ``[k]`` bool, a rigid-body or mechanism mode.
        unstable: ``[k]`` bool, ``omega^2`` clearly negative.
    """

    eigenvalue: Array
    angular_frequency: Array
    frequency: Array
    shape: Array
    node_displacement: Array
    zero_frequency: Array
    unstable: Array


def node_positions(structure: Structure, geometry, state: dict) -> Array:
    """Every node's position ``[N + P0, 3]`` [m] (tube nodes, then point nodes)."""
    config = tube_configuration(structure, geometry, state)
    parts = [jnp.zeros((0, 3))]
    if config is not None:
        parts.append(config.node_position)
    own = structure.elements.own_point_count
    if own:
        parts.append(state["point_position"][:own])
    return jnp.concatenate(parts)


def null_space(jacobian: Array) -> Array:
    """A basis ``[n, n - m]`` of the null space of a full-row-rank ``jacobian`` ``[m, n]``,
    differentiable in it (module docstring): ``m`` independent columns ``B`` of ``J`` (the
    pivots of an LU factorisation of ``J^T`` with partial pivoting, derivative stopped) are
    eliminated, ``Z[B] = -J_B^{-1} J_F``, ``Z[F] = I`` (``F`` the other columns)."""
    m, n = jacobian.shape
    if m == 0:
        return jnp.eye(n)
    _, _, order = jax.lax.linalg.lu(jax.lax.stop_gradient(jacobian.T))
    basic, free = order[:m], order[m:]
    eliminated = -jnp.linalg.solve(jacobian[:, basic], jacobian[:, free])
    return (jnp.zeros((n, n - m), jacobian.dtype).at[basic].set(eliminated)
            .at[free].set(jnp.eye(n - m, dtype=jacobian.dtype)))


def stiffness_and_mass(structure: Structure, params: StructureParameters, state: dict,
                       multipliers: Array) -> tuple[Array, Array, Array]:
    """``K [n, n]`` (Hessian of the Lagrangian), ``M [n, n]`` and ``J [m, n]`` at a state."""
    geometry = tube_reference_geometry(structure, params)
    z, unravel = ravel_pytree(state)
    stiffness = dense_from_blocks(state, lagrangian_hessian_blocks(
        structure, geometry, params, None, state, multipliers))
    stiffness = 0.5 * (stiffness + stiffness.T)

    def constraint_values(flat):
        s = unravel(flat)
        return constraints(structure, tube_configuration(structure, geometry, s), s, params,
                           None)

    jacobian = jax.jacfwd(constraint_values)(z)
    return stiffness, mass_matrix(structure, params, geometry, state), jacobian


@eqx.filter_jit
def modes(structure: Structure, params: StructureParameters, solution: Solution,
          count: int | None = None, zero_tolerance: float = 1e-8) -> Modes:
    """The ``count`` lowest natural modes (all when ``None``) of ``structure`` about the
    equilibrium ``solution`` (from :func:`jaxtube.equilibrium` with the same ``params``; a
    solution under a displacement control is taken without the control).

    Differentiable in ``params`` (through the solution's implicit derivative) for distinct
    eigenvalues; ``jit`` it with ``structure`` static. See the module docstring.

    Example::

        solution = jt.equilibrium(structure, params)
        first = jt.modes(structure, params, solution, count=3).frequency  # [3] Hz
    """
    state = solution.state
    geometry = tube_reference_geometry(structure, params)
    multipliers = solution.multipliers[: constraint_count_of(structure, params, state)]
    stiffness, mass, jacobian = stiffness_and_mass(structure, params, state, multipliers)
    basis = null_space(jacobian)
    reduced_mass = basis.T @ mass @ basis
    factor = jnp.linalg.cholesky(0.5 * (reduced_mass + reduced_mass.T))
    left = jax.scipy.linalg.solve_triangular(factor, basis.T @ stiffness @ basis, lower=True)
    symmetric = jax.scipy.linalg.solve_triangular(factor, left.T, lower=True)
    eigenvalue, vectors = jnp.linalg.eigh(0.5 * (symmetric + symmetric.T))
    reduced_shape = jax.scipy.linalg.solve_triangular(factor.T, vectors, lower=False)
    shape = (basis @ reduced_shape).T
    if count is not None:
        eigenvalue, shape = eigenvalue[:count], shape[:count]
    z, unravel = ravel_pytree(state)
    _, node_motion = jax.vmap(lambda v: jax.jvp(
        lambda flat: node_positions(structure, geometry, unravel(flat)), (z,), (v,)))(shape)
    scale = jnp.maximum(jnp.max(jnp.abs(eigenvalue)), 1e-300)
    zero = jnp.abs(eigenvalue) <= zero_tolerance * scale
    angular = jnp.sqrt(jnp.where(eigenvalue > 0, eigenvalue, 0.0))
    return Modes(eigenvalue=eigenvalue, angular_frequency=angular,
                 frequency=angular / (2 * jnp.pi), shape=shape, node_displacement=node_motion,
                 zero_frequency=zero, unstable=(eigenvalue < 0) & ~zero)


def constraint_count_of(structure: Structure, params: StructureParameters,
                        state: dict) -> int:
    """The number of constraints without a control (static)."""
    geometry = tube_reference_geometry(structure, params)
    shape = jax.eval_shape(lambda s: constraints(
        structure, tube_configuration(structure, geometry, s), s, params, None), state)
    return shape.shape[0]
