"""The Newton-KKT iteration without nested data-dependent loops (``globalisation="fixed_trials"``).

The default iteration (``"backtracking"``, :mod:`jaxtube._solver.newton_kkt`) runs two while
loops inside each Newton step: the regularisation retries of the curvature test and the
backtracking line search. Under ``vmap`` every loop runs in lockstep, so each member pays
for any member's retries, pass by pass. Here one *pass* of a single while loop does a fixed
amount of work, and what the nested loops did becomes state carried from pass to pass:

- *Regularisation level* ``r`` (per member): each pass solves the KKT system once, with
  ``mu = MU_FLOOR h`` for ``r = -1`` and ``mu = 1e-8 * 10^r h`` for ``r >= 0`` (``h`` the
  Hessian's largest diagonal entry: the same sequence as the retries). If the curvature test
  (Chiang & Zavala 2016) fails, the member does not move and the next pass retries one level
  up; after ``max_regularisations`` levels the step is taken anyway, as by the retries.
  After a step the level starts again at ``r = -1``.
- *Trial step lengths*: the full step is tested as before (Armijo on the l1 merit, or it
  halves the KKT residual); if it is refused, ``line_search_trials`` step lengths
  ``alpha = 2^-(b+f) .. 2^-(b+f+T-1)`` along the same curve with its second-order correction
  (:mod:`jaxtube._solver.kkt_step`) are evaluated together (``vmap`` over the merit) and the
  largest that satisfies Armijo is taken (``f = 0`` where there is a correction: the
  corrected full step first, as the backtracking iteration; ``f = 1`` without one). If none
  does, the member stays and the next pass continues from ``b + T``; past
  ``max_backtracks`` halvings the line search has failed (code 2), as before.

Each pass of a member at a given state recomputes the same linearisation, so a member's
iterates are those of the backtracking iteration (same regularisations, same step lengths,
same stopping rule); what changes is the work a batch shares. The trials are evaluated only
in passes where some member needs them (a one-pass loop, :func:`_unless`), so a single solve
whose full steps are accepted pays nothing for them.

The gradient rows (each energy term's gradient and the constraint Jacobian) computed at the
full-step trial point are kept: when the full step is accepted they are the next pass's
rows, and the pass does not linearise the objective again.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp

from .kkt_step import all_finite, first_trial_exponent, regularised_step, second_order_correction


class Linearisation(NamedTuple):
    """What the Newton solver knows about the problem (closures over ``args``)."""

    rows: Callable  # z -> (energy, c [m], part_grads [k, n], jacobian [m, n])
    hessian: Callable  # (z, lam) -> the Hessian in the route's form
    merit_parts: Callable  # z -> (energy, c [m])
    route: object  # DenseKKT or SparseKKT
    unless: Callable  # (skip, step, skipped) -> one-pass while loop


def _residuals(solver, rows, lam):
    """KKT gradient residual, constraint residual, the stopping rule's verdict."""
    e, c, part_grads, jacobian = rows
    grad_e = jnp.sum(part_grads, axis=0)
    jt_lam = jacobian.T @ lam
    res_g = jnp.max(jnp.abs(grad_e + jt_lam))
    res_c = jnp.max(jnp.abs(c), initial=0.0)
    # The stopping rule of the backtracking iteration (newton_kkt's module docstring).
    scale = jnp.maximum(jnp.max(jnp.abs(part_grads)), jnp.max(jnp.abs(jt_lam)))
    converged = (res_g <= solver.rtol * scale + solver.atol) & (res_c <= solver.constraint_tol)
    return grad_e, res_g, res_c, converged


def fixed_trials_loop(problem: Linearisation, solver, z0, lam0, mu_floor: float):
    """Run the iteration; returns ``(z, lam, steps, code, res_g, res_c)`` (codes as
    :data:`jaxtube.RESULTS`). ``solver`` is a ``NewtonKKT``."""
    n = z0.shape[0]
    dtype = z0.dtype
    route = problem.route
    trials = solver.line_search_trials
    last_level = solver.max_regularisations - 1

    def newton_pass(z, lam, rho, rows, level, halvings):
        """One linearisation, one KKT solve, the trial steps. Returns the candidate state
        and what the member does next."""
        e, c, _, jacobian = rows
        grad_e, res_g, res_c, _ = _residuals(solver, rows, lam)
        hessian = problem.hessian(z, lam)
        finite = all_finite(hessian)
        h_scale = jnp.maximum(jnp.max(jnp.abs(route.hessian_diagonal(hessian))), 1e-300)
        j_scale = route.jacobian_scale(hessian, jacobian)
        mu = jnp.where(level < 0, mu_floor,
                       1e-8 * 10.0 ** jnp.maximum(level, 0).astype(dtype)) * h_scale
        sol, curvature_ok, factors = regularised_step(route, hessian, jacobian, grad_e, c, lam,
                                                      mu, h_scale, j_scale)
        dz, lam_new = sol[:n], sol[n:]
        proceed = curvature_ok | (level >= last_level)

        rho_new = jnp.maximum(rho, 2.0 * jnp.max(jnp.abs(lam_new), initial=0.0) + 1e-12)
        violation = jnp.sum(jnp.abs(c))
        phi0 = e + rho_new * violation
        slope = grad_e @ dz - rho_new * violation
        full_rows = problem.rows(z + dz)
        full_e, full_c = full_rows[0], full_rows[1]
        _, full_g, full_cn, _ = _residuals(solver, full_rows, lam_new)
        full_ok = (full_g <= 0.5 * res_g) & (full_cn <= jnp.maximum(0.5 * res_c,
                                                                  solver.constraint_tol))
        armijo_full = full_e + rho_new * jnp.sum(jnp.abs(full_c)) <= phi0 + 1e-4 * slope
        full_accepted = (halvings == 0) & (full_ok | armijo_full)

        def trial_steps(_):
            """The next ``trials`` halvings along ``z + a dz + a^2 s`` (``s`` the second-order
            correction, as the backtracking iteration), evaluated together; the largest
            accepted, and the point it reaches."""
            correction = (second_order_correction(route, factors, c, jacobian @ dz, dz,
                                                full_c)
                          if c.shape[0] else jnp.zeros_like(dz))
            exponent = (halvings + first_trial_exponent(correction)
                        + jnp.arange(trials, dtype=jnp.int32))
            alphas = 0.5 ** exponent.astype(dtype)
            e_t, c_t = jax.vmap(
                lambda a: problem.merit_parts(z + a * dz + a**2 * correction))(alphas)
            merit = e_t + rho_new * jnp.sum(jnp.abs(c_t), axis=1)
            ok = (merit <= phi0 + 1e-4 * alphas * slope) & (exponent <= solver.max_backtracks)
            alpha = jnp.where(jnp.any(ok), alphas[jnp.argmax(ok)], 0.0)
            return alpha, z + alpha * dz + alpha**2 * correction

        alpha, z_trial = problem.unless(full_accepted | ~proceed, trial_steps,
                                        (jnp.zeros((), dtype), z))
        alpha = jnp.where(full_accepted, 1.0, alpha)
        z_next = jnp.where(full_accepted, z + dz, z_trial)
        moved = proceed & (alpha > 0.0)
        exhausted = proceed & ~moved & (halvings + trials >= solver.max_backtracks)
        finite = finite & jnp.all(jnp.isfinite(dz))
        return (z_next, lam + alpha * (lam_new - lam), rho_new, moved, proceed,
                exhausted, finite, full_accepted, full_rows)

    def body(carry):
        z, lam, rho, step, _, _, _, _, rows, rows_valid, level, halvings = carry
        rows = problem.unless(rows_valid, lambda _: problem.rows(z), rows)
        _, res_g, res_c, converged = _residuals(solver, rows, lam)
        finite_residual = jnp.isfinite(res_g) & jnp.isfinite(res_c)

        def stay(_):
            false = jnp.zeros((), bool)
            return (z, lam, rho, false, false, false, jnp.ones((), bool), false, rows)

        (z_try, lam_try, rho_try, moved, proceed, exhausted, finite_step, full_accepted,
         full_rows) = problem.unless(converged | ~finite_residual,
                                     lambda _: newton_pass(z, lam, rho, rows, level, halvings),
                                     stay(None))
        finite = finite_residual & finite_step
        stop = converged | ~finite | exhausted
        moved = moved & ~stop
        code = jnp.where(converged, 0, jnp.where(~finite, 3, jnp.where(exhausted, 2, 1)))
        # Next pass: a step resets the level and the halvings; a refused curvature raises the
        # level; a refused set of trials continues the halvings.
        level_next = jnp.where(moved, -1, jnp.where(proceed, level, level + 1))
        halvings_next = jnp.where(moved | ~proceed, 0, halvings + trials)
        keep = moved & full_accepted
        rows_next = jax.tree.map(lambda new, old: jnp.where(keep, new, old), full_rows, rows)
        return (jnp.where(moved, z_try, z), jnp.where(moved, lam_try, lam),
                jnp.where(moved, rho_try, rho), step + moved.astype(jnp.int32), stop,
                code.astype(jnp.int32), res_g, res_c, rows_next, keep | ~moved,
                level_next.astype(jnp.int32), halvings_next.astype(jnp.int32))

    def cond(carry):
        step, stop = carry[3], carry[4]
        return (~stop) & (step < solver.max_steps)

    rows0 = jax.eval_shape(problem.rows, z0)
    rows0 = jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), rows0)
    int0 = jnp.zeros((), jnp.int32)
    init = (z0, lam0, jnp.zeros((), dtype), int0, jnp.zeros((), bool), jnp.ones((), jnp.int32),
            jnp.full((), jnp.inf, dtype), jnp.full((), jnp.inf, dtype), rows0,
            jnp.zeros((), bool), jnp.full((), -1, jnp.int32), int0)
    z, lam, _, steps, _, code, res_g, res_c = jax.lax.while_loop(cond, body, init)[:8]
    return z, lam, steps, code, res_g, res_c
