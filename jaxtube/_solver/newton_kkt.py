"""Equality-constrained energy minimisation with Newton's method, and its implicit gradient.

Problem: ``min_y E(y, args)`` subject to ``c(y, args) = 0``, where ``y`` is any PyTree (the
structure's state) and ``args`` any PyTree of parameters; one objective function returns
``(E, c)`` so that their shared work (the kinematics) is done once. Stationarity of the Lagrangian
``L = E + lambda . c`` gives the KKT system, solved by Newton's method with the exact
Hessian (forward-over-reverse automatic differentiation):

    [H + mu I   J^T] [dy        ]     [-grad E]
    [J          0  ] [lambda_new]  =  [-c     ]

Globalisation:

- *Inertia-free curvature test* (Chiang & Zavala 2016): the step is accepted only if
  ``dy^T (H + mu I) dy >= eps |dy|^2``; otherwise ``mu`` grows tenfold and the system is
  solved again. This keeps the reduced Hessian positive definite, so the iteration heads for
  minima, not saddles (a root of the gradient can be a saddle).
- *Backtracking line search* (Armijo) on the l1 exact-penalty merit
  ``E + rho |c|_1`` with ``rho > |lambda_new|_inf`` (Nocedal & Wright 2006, section 18.3).
  A full step is also taken when it halves the KKT residual, which avoids the Maratos
  effect and round-off stalls near the solution.

Gradients through the solution use the implicit function theorem: at ``F(y*, lambda*,
args) = 0`` (``F`` the KKT residual) the tangent is ``-K^{-1} dF/dargs . dargs``, with ``K``
the KKT matrix. It is written as a ``jax.custom_jvp``; reverse mode follows by JAX's
transposition of that linear map, so no while-loop is ever differentiated.

The solve never raises inside traced code: it returns a :class:`EquilibriumResult` with a
``result`` code (:data:`RESULT_MESSAGES`), and callers turn codes into words.
"""

from __future__ import annotations

from functools import partial

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.flatten_util import ravel_pytree

from .results import RESULTS, result_messages

RESULT_MESSAGES = result_messages(RESULTS)


class NewtonKKT(eqx.Module):
    """Settings of the Newton solver. Tolerances are floats; counts are static.

    Attributes:
        rtol: KKT gradient residual relative to the size of the balancing force terms.
        atol: absolute gradient residual [N m or N] (needed at zero load).
        constraint_tol: absolute constraint residual [m].
        max_steps: Newton steps per solve.
        max_backtracks: halvings of the step in the line search.
        max_regularisations: tenfold increases of ``mu`` in the curvature test.
    """

    rtol: float = 1e-10
    atol: float = 1e-12
    constraint_tol: float = 1e-11
    max_steps: int = eqx.field(static=True, default=60)
    max_backtracks: int = eqx.field(static=True, default=30)
    max_regularisations: int = eqx.field(static=True, default=12)


class EquilibriumResult(eqx.Module):
    """Result of one equilibrium solve.

    Attributes:
        state: the equilibrium state (same PyTree as the initial guess).
        multipliers: Lagrange multipliers of the constraints, shape ``[m]``.
        converged: bool. iterations: Newton steps taken. result: code, see RESULT_MESSAGES.
        residual: KKT gradient residual (inf-norm). constraint_violation: inf-norm of ``c``.
    """

    state: object
    multipliers: Array
    converged: Array
    iterations: Array
    result: Array
    residual: Array
    constraint_violation: Array


def _kkt_matrix(hessian, jacobian, mu, delta=0.0):
    n, m = hessian.shape[0], jacobian.shape[0]
    top = jnp.concatenate([hessian + mu * jnp.eye(n, dtype=hessian.dtype), jacobian.T], axis=1)
    bottom = jnp.concatenate([jacobian, -delta * jnp.eye(m, dtype=hessian.dtype)], axis=1)
    return jnp.concatenate([top, bottom], axis=0)


def _newton(objective, hessian_fn, solver: NewtonKKT, args, z0, lam0):
    n = z0.shape[0]
    eye = jnp.eye(n, dtype=z0.dtype)

    def lagrangian_and_parts(z, lam):
        e, c = objective(z, args)
        return e + jnp.dot(lam, c), (e, c)

    def gradient_and_parts(z, lam):
        (_, (e, c)), grad = jax.value_and_grad(lagrangian_and_parts, has_aux=True)(z, lam)
        return grad, e, c

    def merit(z, rho):
        e, c = lagrangian_and_parts(z, jnp.zeros_like(lam0))[1]
        return e + rho * jnp.sum(jnp.abs(c))

    def body(carry):
        z, lam, rho, step, _, _, _, _, _ = carry
        if hessian_fn is None:
            # One linearisation gives the gradient, the energy, the constraints and, by
            # pushing the identity through it, the Lagrangian Hessian and the constraint
            # Jacobian.
            (grad_l, e, c), tangent = jax.linearize(lambda zz: gradient_and_parts(zz, lam), z)
            hessian, _, jacobian_t = jax.vmap(tangent)(eye)
            jacobian = jacobian_t.T
        else:
            grad_l, e, c = gradient_and_parts(z, lam)
            jacobian = jax.jacrev(lambda zz: objective(zz, args)[1])(z)
            jacobian_t = jacobian.T
            hessian = hessian_fn(z, lam, args)
        hessian = 0.5 * (hessian + hessian.T)
        jt_lam = jacobian_t @ lam
        grad_e = grad_l - jt_lam
        res_g = jnp.max(jnp.abs(grad_l))
        res_c = jnp.max(jnp.abs(c), initial=0.0)
        scale = jnp.maximum(
            jnp.max(jnp.abs(grad_e)), jnp.maximum(jnp.max(jnp.abs(jt_lam)),
                                                  jnp.max(jnp.abs(hessian @ z)))
        )
        converged = (res_g <= solver.rtol * scale + solver.atol) & (res_c <= solver.constraint_tol)
        finite = jnp.isfinite(res_g) & jnp.isfinite(res_c) & jnp.all(jnp.isfinite(hessian))

        # Curvature test with growing regularisation (inertia-free).
        h_scale = jnp.maximum(jnp.max(jnp.abs(jnp.diag(hessian))), 1e-300)
        j_scale = jnp.max(jnp.abs(jacobian), initial=1.0)

        def solve_with(mu):
            # Redundant constraints (e.g. an inextensible straight tube between two pins)
            # make J rank deficient: regularised tries add a proximal term on the
            # multipliers, -delta (lambda_new - lambda), which vanishes at a solution.
            delta = (1e-10 + mu / h_scale) * j_scale**2 / h_scale
            rhs = jnp.concatenate([-grad_e, -c - delta * lam])
            sol = jnp.linalg.solve(_kkt_matrix(hessian, jacobian, mu, delta), rhs)
            dz = sol[:n]
            curvature = dz @ (hessian @ dz) + mu * (dz @ dz)
            ok = (curvature >= 1e-10 * h_scale * (dz @ dz)) & jnp.all(jnp.isfinite(sol))
            return sol, ok

        def reg_cond(rc):
            _, ok, tries, _ = rc
            return (~ok) & (tries < solver.max_regularisations)

        def reg_body(rc):
            _, _, tries, mu = rc
            mu = jnp.where(mu == 0.0, 1e-8 * h_scale, 10.0 * mu)
            sol, ok = solve_with(mu)
            return sol, ok, tries + 1, mu

        sol0, ok0 = solve_with(jnp.zeros((), dtype=z.dtype))
        sol, _, _, _ = jax.lax.while_loop(
            reg_cond, reg_body, (sol0, ok0, jnp.zeros((), jnp.int32), jnp.zeros((), z.dtype))
        )
        dz, lam_new = sol[:n], sol[n:]

        rho_new = jnp.maximum(rho, 2.0 * jnp.max(jnp.abs(lam_new), initial=0.0) + 1e-12)
        phi0 = e + rho_new * jnp.sum(jnp.abs(c))
        slope = grad_e @ dz - rho_new * jnp.sum(jnp.abs(c))
        full_grad, full_e, full_c = gradient_and_parts(z + dz, lam_new)
        full_g = jnp.max(jnp.abs(full_grad))
        full_cn = jnp.max(jnp.abs(full_c), initial=0.0)
        full_ok = (full_g <= 0.5 * res_g) & (full_cn <= jnp.maximum(0.5 * res_c,
                                                                  solver.constraint_tol))
        armijo_full = full_e + rho_new * jnp.sum(jnp.abs(full_c)) <= phi0 + 1e-4 * slope

        def ls_cond(lc):
            alpha, accepted, k = lc
            return (~accepted) & (k < solver.max_backtracks)

        def ls_body(lc):
            alpha, _, k = lc
            alpha = 0.5 * alpha
            accepted = merit(z + alpha * dz, rho_new) <= phi0 + 1e-4 * alpha * slope
            return alpha, accepted, k + 1

        alpha, accepted, _ = jax.lax.while_loop(
            ls_cond, ls_body, (jnp.ones((), z.dtype), full_ok | armijo_full,
                               jnp.zeros((), jnp.int32))
        )
        finite = finite & jnp.all(jnp.isfinite(dz))
        stop = converged | ~finite | ~accepted
        code = jnp.where(converged, 0, jnp.where(~finite, 3, jnp.where(~accepted, 2, 1)))
        code = code.astype(jnp.int32)
        z_next = jnp.where(stop, z, z + alpha * dz)
        lam_next = jnp.where(stop, lam, lam + alpha * (lam_new - lam))
        # The KKT matrix at the current point: when the loop stops here it is the matrix at
        # the returned solution, reused by the implicit-function-theorem tangent.
        kkt = _kkt_matrix(hessian, jacobian, jnp.zeros((), z.dtype))
        return (z_next, lam_next, rho_new, step + jnp.where(stop, 0, 1).astype(jnp.int32), stop,
                code, res_g, res_c, kkt)

    def cond(carry):
        _, _, _, step, stop, _, _, _, _ = carry
        return (~stop) & (step < solver.max_steps)

    dtype = z0.dtype
    m = lam0.shape[0]
    init = (z0, lam0, jnp.zeros((), dtype), jnp.zeros((), jnp.int32), jnp.zeros((), bool),
            jnp.ones((), jnp.int32), jnp.full((), jnp.inf, dtype), jnp.full((), jnp.inf, dtype),
            jnp.full((n + m, n + m), jnp.nan, dtype))
    z, lam, _, steps, _, code, res_g, res_c, kkt = jax.lax.while_loop(cond, body, init)
    return z, lam, (code == 0, steps, code, res_g, res_c), kkt


@partial(jax.custom_jvp, nondiff_argnums=(0, 1, 2))
def _equilibrium(objective, hessian_fn, solver, args, z0, lam0):
    z, lam, stats, _ = _newton(objective, hessian_fn, solver, args, z0, lam0)
    return z, lam, stats


def _kkt_residual(objective, z, lam, args):
    def lagrangian(zz):
        e, c = objective(zz, args)
        return e + jnp.dot(lam, c), c

    grad, c = jax.grad(lagrangian, has_aux=True)(z)
    return jnp.concatenate([grad, c])


@_equilibrium.defjvp
def _equilibrium_jvp(objective, hessian_fn, solver, primals, tangents):
    args, z0, lam0 = primals
    args_dot = tangents[0]
    z, lam, stats, kkt = _newton(objective, hessian_fn, solver, args, z0, lam0)
    n = z.shape[0]
    _, residual_dot = jax.jvp(
        lambda a: _kkt_residual(objective, z, lam, a), (args,), (args_dot,)
    )
    solution_dot = -jnp.linalg.solve(kkt, residual_dot)
    stats_dot = tuple(
        jnp.zeros_like(s) if jnp.issubdtype(s.dtype, jnp.inexact)
        else np.zeros(s.shape, dtype=jax.dtypes.float0)
        for s in stats
    )
    return (z, lam, stats), (solution_dot[:n], solution_dot[n:], stats_dot)


def solve_equilibrium(
    objective,
    initial_state,
    args,
    solver: NewtonKKT = NewtonKKT(),
    initial_multipliers: Array | None = None,
    hessian=None,
) -> EquilibriumResult:
    """Minimise an energy subject to equality constraints, both from one ``objective``.

    Args:
        objective: ``(state, args) -> (energy, constraints)``: the total potential energy
            [J] (scalar) and the equality constraints ``[m]`` (``m`` may be 0). One function
            for both, so that shared work (the structure's kinematics) is done once.
        initial_state: PyTree initial guess (e.g. the previous load step).
        args: PyTree of parameters; derivatives of the result w.r.t. it come from the
            implicit function theorem.
        solver: :class:`NewtonKKT` settings.
        initial_multipliers: ``[m]`` warm start for the multipliers.
        hessian: optional ``(state, multipliers, args) -> [n, n]``, the exact Hessian of the
            Lagrangian ``E + multipliers . c`` w.r.t. the state flattened as by
            ``jax.flatten_util.ravel_pytree``; a model that knows its sparsity assembles it
            much faster than the default (dense forward-over-reverse autodiff).

    Works under ``jit``, ``vmap`` (each member reports its own convergence), ``grad`` and
    ``jvp``. Requires float64 (see the README): float32 cannot reach Newton tolerances.
    """
    z0, unravel = ravel_pytree(initial_state)
    if z0.dtype != jnp.float64:
        raise TypeError(
            "jaxtube needs float64: enable it with jax.config.update('jax_enable_x64', True) "
            "before creating arrays (importing jaxtube does this unless JAXTUBE_NO_X64=1)."
        )

    def flat_objective(z, a):
        energy, constraints = objective(unravel(z), a)
        return energy, jnp.reshape(constraints, (-1,))

    flat_hessian = None
    if hessian is not None:
        def flat_hessian(z, lam, a):
            return hessian(unravel(z), lam, a)

    m = jax.eval_shape(flat_objective, z0, args)[1].shape[0]
    lam0 = jnp.zeros((m,), z0.dtype) if initial_multipliers is None else initial_multipliers
    z, lam, (converged, steps, code, res_g, res_c) = _equilibrium(
        flat_objective, flat_hessian, solver, args, z0, lam0
    )
    return EquilibriumResult(
        state=unravel(z), multipliers=lam, converged=converged, iterations=steps, result=code,
        residual=res_g, constraint_violation=res_c,
    )
