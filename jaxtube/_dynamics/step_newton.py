"""The Newton iteration of one implicit time step, and its implicit derivative.

Each step of :mod:`.integrator` minimises an incremental potential under the structure's
constraints. The static solver (:func:`jaxtube._solver.newton_kkt.solve_equilibrium`) would do,
but it is built for problems far from their solution: every iteration it evaluates the
gradient at the full step ``z + dz`` for its acceptance test and then again at the start of
the next iteration, and it stops only after one more gradient evaluation at the solution. A
time step is a different problem: near the predictor the inertia ``4 M / h^2`` dominates the
Hessian, so Newton's iteration from a good guess converges in two or three steps without any
globalisation. This iteration therefore evaluates the objective once per iterate:

- The energy terms, their gradients, the constraints and ``J^T lambda`` at an iterate come
  from one forward pass and ``k + 1`` batched reverse passes (``k`` energy terms).
- That one evaluation serves three purposes: the acceptance of the step that led there, the
  stopping rule at the new iterate, and the right-hand side of the next Newton system. There
  is no separate check evaluation.
- Stopping rule: the static solver's, force-scaled (its module docstring):
  ``|grad E + J^T lambda|_inf <= rtol * scale + atol`` and ``|c|_inf <= constraint_tol``,
  ``scale = max(max_k |grad E_k|_inf, |J^T lambda|_inf)``.
- Safeguards: the static solver's, minus the second-order correction. The KKT system is
  solved with the floor regularisation and the inertia-free curvature test (Chiang & Zavala
  2016; ``mu`` grows tenfold while it fails, :func:`jaxtube._solver.kkt_step.regularised_step`).
  A trial iterate ``z + alpha dz`` is accepted if it halves the KKT residual or decreases
  the l1 merit ``E + rho |c|_1`` by Armijo's rule (Nocedal & Wright 2006, section 18.3);
  otherwise ``alpha`` halves and the trial is evaluated again from the same Newton direction
  (no new Hessian). A hard step (a slack line going taut, a large rotation) thus still
  converges, or ends with a code: ``max_steps`` Newton iterations without convergence (1),
  ``max_backtracks`` halvings without acceptance (2), non-finite values (3); never passed over.

The start is the caller's guess (:mod:`.integrator` extrapolates the last three steps), and
the iterate count is the number of Newton systems solved.

Gradients: the implicit function theorem at the solution, as the static solver's
(``-K^{-1} dF/dargs``, ``K`` the KKT matrix with the floor regularisation, solved on the same
route), written as a ``jax.custom_jvp``, so no loop is differentiated and reverse mode
follows by transposition.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
from jax.flatten_util import ravel_pytree

from .._solver.kkt_route import kkt_route
from .._solver.kkt_step import all_finite, regularised_step
from .._solver.newton_kkt import (
    MU_FLOOR,
    EquilibriumResult,
    NewtonKKT,
    _kkt_at_solution,
    _lagrangian_hessian,
    implicit_tangent,
)


def _evaluate(objective, args, z, lam, k, m, needs_jacobian):
    """Everything the iteration needs at ``(z, lam)``: ``(energy, c [m], grad_e [n], J^T lam
    [n], scale, jacobian [m, n] or None)``; ``scale`` is the stopping rule's largest
    generalised force of any one energy term or of the reactions."""
    (terms, c), pullback = jax.vjp(lambda zz: objective(zz, args), z)
    dtype = z.dtype
    # k cotangents picking each energy term, then one carrying the multipliers.
    term_cotangents = jnp.concatenate([jnp.eye(k, dtype=dtype), jnp.zeros((1, k), dtype)])
    constraint_cotangents = jnp.concatenate([jnp.zeros((k, m), dtype), lam[None]])
    if needs_jacobian:
        constraint_cotangents = jnp.concatenate(
            [constraint_cotangents, jnp.eye(m, dtype=dtype)])
        term_cotangents = jnp.concatenate([term_cotangents, jnp.zeros((m, k), dtype)])
    (pulled,) = jax.vmap(pullback)((term_cotangents, constraint_cotangents))
    part_grads, jt_lam = pulled[:k], pulled[k]
    jacobian = pulled[k + 1:] if needs_jacobian else None
    scale = jnp.maximum(jnp.max(jnp.abs(part_grads)), jnp.max(jnp.abs(jt_lam)))
    return jnp.sum(terms), c, jnp.sum(part_grads, axis=0), jt_lam, scale, jacobian


def _step_newton(objective, hessian_fn, solver: NewtonKKT, args, z0, lam0):
    n, m = z0.shape[0], lam0.shape[0]
    k = jax.eval_shape(objective, z0, args)[0].shape[0]
    dtype = z0.dtype
    route = kkt_route(hessian_fn, solver.linear_solver, args, z0, lam0)

    def evaluate(z, lam):
        """``(energy, c, grad_e, jacobian, residuals [2], converged, finite)`` at ``(z,
        lam)``."""
        e, c, grad_e, jt_lam, scale, jacobian = _evaluate(objective, args, z, lam, k, m,
                                                          route.needs_jacobian)
        residual = jnp.stack([jnp.max(jnp.abs(grad_e + jt_lam)),
                              jnp.max(jnp.abs(c), initial=0.0)])
        converged = ((residual[0] <= solver.rtol * scale + solver.atol)
                     & (residual[1] <= solver.constraint_tol))
        return e, c, grad_e, jacobian, residual, converged, jnp.all(jnp.isfinite(residual))

    def body(carry):
        base, lam, at_base, rho, alpha, tries, iterations, _, _ = carry
        e, c, grad_e, jacobian, residual, _, _ = at_base
        # The Newton direction at the base: the floor regularisation first, then ``mu``
        # from 1e-8 of the Hessian's scale up tenfold while the curvature test fails.
        hessian = _lagrangian_hessian(objective, hessian_fn, route, args, base, lam)
        h_scale = jnp.maximum(jnp.max(jnp.abs(route.hessian_diagonal(hessian))), 1e-300)
        mu = jnp.where(tries == 0, MU_FLOOR, 1e-8 * 10.0 ** (tries - 1).astype(dtype)) * h_scale
        solution, curvature_ok, _ = regularised_step(
            route, hessian, jacobian, grad_e, c, lam, mu, h_scale,
            route.jacobian_scale(hessian, jacobian))
        # Past the last regularisation the step is taken as it is (as the static solver).
        usable = curvature_ok | ((tries >= solver.max_regularisations)
                                 & jnp.all(jnp.isfinite(solution)))
        dz, lam_new = solution[:n], solution[n:]
        rho = jnp.maximum(rho, 2.0 * jnp.max(jnp.abs(lam_new), initial=0.0) + 1e-12)
        violation = jnp.sum(jnp.abs(c))
        trial = base + alpha * dz
        lam_trial = lam + alpha * (lam_new - lam)
        at_trial = evaluate(trial, lam_trial)
        e_t, c_t, _, _, residual_t, converged_t, finite_t = at_trial
        # The trial halves the KKT residual, or decreases the l1 merit by Armijo's rule.
        halved = (residual_t[0] <= 0.5 * residual[0]) & (
            residual_t[1] <= jnp.maximum(0.5 * residual[1], solver.constraint_tol))
        armijo = (e_t + rho * jnp.sum(jnp.abs(c_t))
                  <= e + rho * violation + 1e-4 * alpha * (grad_e @ dz - rho * violation))
        accepted = usable & finite_t & (halved | armijo)
        keep = lambda new, old: jax.tree.map(partial(jnp.where, accepted), new, old)  # noqa: E731
        iterations = iterations + 1
        alpha = jnp.where(accepted, 1.0, jnp.where(usable, 0.5 * alpha, alpha))
        tries = jnp.where(accepted, 0, jnp.where(usable, tries, tries + 1))
        converged = accepted & converged_t
        nonfinite = ~all_finite(hessian)
        exhausted = alpha < 0.5 ** solver.max_backtracks
        stop = converged | nonfinite | exhausted | (iterations >= solver.max_steps)
        code = jnp.where(converged, 0, jnp.where(nonfinite, 3, jnp.where(exhausted, 2, 1)))
        return (keep(trial, base), keep(lam_trial, lam), keep(at_trial, at_base), rho, alpha,
                tries, iterations, stop, code.astype(jnp.int32))

    at_start = evaluate(z0, lam0)
    converged, finite = at_start[5], at_start[6]
    code = jnp.where(converged, 0, jnp.where(finite, 1, 3)).astype(jnp.int32)
    init = (z0, lam0, at_start, jnp.zeros((), dtype), jnp.ones((), dtype),
            jnp.zeros((), jnp.int32), jnp.zeros((), jnp.int32), converged | ~finite, code)
    z, lam, at_end, _, _, _, iterations, _, code = jax.lax.while_loop(
        lambda carry: ~carry[7], body, init)
    residual = at_end[4]
    return z, lam, (code == 0, iterations, code, residual[0], residual[1])


@partial(jax.custom_jvp, nondiff_argnums=(0, 1, 2))
def _step_solution(objective, hessian_fn, solver, args, z0, lam0):
    return _step_newton(objective, hessian_fn, solver, args, z0, lam0)


@_step_solution.defjvp
def _step_solution_jvp(objective, hessian_fn, solver, primals, tangents):
    args, z0, lam0 = primals
    z, lam, stats = _step_solution(objective, hessian_fn, solver, args, z0, lam0)
    route = kkt_route(hessian_fn, solver.linear_solver, args, z0, lam0)
    kkt = _kkt_at_solution(objective, hessian_fn, route, args, z, lam)
    return (z, lam, stats), implicit_tangent(objective, route, args, tangents[0], z, lam, kkt,
                                             stats)


def solve_step(objective, guess, args, solver: NewtonKKT, multipliers, hessian,
               constraint_factors=None) -> EquilibriumResult:
    """One time step's minimisation (module docstring) from ``guess`` (a state PyTree) and
    ``multipliers [m]``; ``objective``, ``hessian`` and ``constraint_factors`` as
    :func:`jaxtube._solver.newton_kkt.solve_equilibrium` takes them (``hessian`` required:
    blocks or a matrix). Returns its :class:`jaxtube._solver.newton_kkt.EquilibriumResult`,
    with ``iterations`` the Newton systems solved."""
    z0, unravel = ravel_pytree(guess)

    def flat_objective(z, a):
        energy, constraints = objective(unravel(z), a)
        return jnp.reshape(energy, (-1,)), jnp.reshape(constraints, (-1,))

    def flat_hessian(z, lam, a):
        return hessian(unravel(z), lam, a)

    flat_hessian.constraint_pattern = None
    flat_hessian.constraint_factors = (None if constraint_factors is None
                                       else (lambda z, a: constraint_factors(unravel(z), a)))
    z, lam, (converged, iterations, code, res_g, res_c) = _step_solution(
        flat_objective, flat_hessian, solver, args, z0, multipliers)
    return EquilibriumResult(state=unravel(z), multipliers=lam, converged=converged,
                             iterations=iterations, result=code, residual=res_g,
                             constraint_violation=res_c)
