"""Equality-constrained energy minimisation with Newton's method, and its implicit gradient.

Problem: ``min_y E(y, args)`` subject to ``c(y, args) = 0``, where ``y`` is any PyTree (the
structure's state) and ``args`` any PyTree of parameters; one objective function returns
``(E, c)`` so that their shared work (the kinematics) is done once. ``E`` may be a vector of
energy terms ``[k]`` (``E = sum_k E_k``: e.g. strain energy, load potential), which sets the
scale of the stopping rule. Stationarity of the Lagrangian
``L = E + lambda . c`` gives the KKT system, solved by Newton's method with the exact
Hessian (forward-over-reverse automatic differentiation):

    [H + mu I   J^T] [dy        ]     [-grad E]
    [J          0  ] [lambda_new]  =  [-c     ]

Stopping rule: converged when ``|grad E + J^T lambda|_inf <= rtol * scale + atol`` and
``|c|_inf <= constraint_tol``, with ``scale = max(max_k |grad E_k|_inf, |J^T lambda|_inf)``:
the largest generalised force of any term making up the residual. It does not involve the
tangent stiffness (which explodes where a law's computed second derivative does), and a
self-equilibrated problem with zero reactions (a ring pushed at two opposite points) still
has its internal and load terms.

The linear systems are solved dense (LAPACK) or sparse (KLU on a static pattern built from
the model's Hessian blocks), chosen by ``NewtonKKT.linear_solver``: ``jaxtube._solver.kkt_linear``.

Globalisation:

- *Inertia-free curvature test* (Chiang & Zavala 2016): the step is accepted only if
  ``dy^T (H + mu I) dy >= eps |dy|^2``; otherwise ``mu`` grows tenfold and the system is
  solved again. This keeps the reduced Hessian positive definite, so the iteration heads for
  minima, not saddles (a root of the gradient can be a saddle).
- *Backtracking line search* (Armijo) on the l1 exact-penalty merit
  ``E + rho |c|_1`` with ``rho > |lambda_new|_inf`` (Nocedal & Wright 2006, section 18.3).
  A full step is also taken when it halves the KKT residual, which avoids the Maratos
  effect and round-off stalls near the solution. The Armijo tests are nonmonotone (Grippo,
  Lampariello & Lucidi 1986; for SQP on this merit, Panier & Tits 1991): they compare with
  the largest merit of the last ``NewtonKKT.nonmonotone_window`` iterates (at the current
  penalty), so a step whose merit rises for a pass through the constraints' curvature is
  taken, not corrected and searched. A refused full step is followed along
  ``z + alpha dz + alpha^2 s`` with the second-order correction ``s`` of curved constraints
  (:mod:`jaxtube._solver.kkt_step`), which avoids the Maratos effect far from it: first the
  corrected full step ``z + dz + s`` (``alpha = 1``; Nocedal & Wright 2006, Algorithm 18.3),
  then the halvings ``alpha = 1/2, 1/4, ...`` (without a correction, the halvings at once).

Each pass of the iteration linearises once: at the proposed full step ``z + dz`` (the
gradients and constraints that decide whether it is taken are those the next Newton step
needs), or, after a line search, at the point it found; the regularisation's trials are one
loop. So the energy's gradient and the KKT factorisation each appear once in the compiled
program (``experiments/bench_compile.py`` measures its size and compile time).

Gradients through the solution use the implicit function theorem: at ``F(y*, lambda*,
args) = 0`` (``F`` the KKT residual) the tangent is ``-K^{-1} dF/dargs . dargs``, with ``K``
the KKT matrix. It is written as a ``jax.custom_jvp``; reverse mode follows by JAX's
transposition of that linear map, so no while-loop is ever differentiated. ``K`` is built from
the Hessian and constraint Jacobian that the iteration evaluated at its last linearised
iterate (the solution, where it converged) and returns beside the solution, so a gradient's
program holds one copy of the Hessian, not two.

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

from .kkt_augmented import AugmentedSparseKKT
from .kkt_route import kkt_route
from .kkt_step import (
    PendingStep,
    RecentMerits,
    all_finite,
    first_trial_exponent,
    regularised_step,
    second_order_correction,
    unless,
)
from .results import RESULTS, result_messages

RESULT_MESSAGES = result_messages(RESULTS)

#: Smallest regularisation of every KKT solve, relative to the Hessian's largest diagonal
#: entry (``mu`` on the Hessian, and ``delta`` on the multipliers in the implicit tangent's
#: matrix). It changes a step by about this relative amount, far below the tolerances, and
#: keeps an exactly singular matrix (a point node whose lines are all slack, a redundant
#: constraint) from a zero pivot: KLU stops the whole program on one (dense LU returns
#: infinities, which the curvature test then rejects).
MU_FLOOR = 1e-14

class NewtonKKT(eqx.Module):
    """Settings of the Newton solver. Tolerances are floats; counts are static.

    Attributes:
        rtol: KKT gradient residual relative to the largest generalised force of any one
            energy term or of the reactions (``max_k |grad E_k|``, ``|J^T lambda|``).
        atol: absolute gradient residual [N m or N] (needed at zero load).
        constraint_tol: absolute constraint residual [m].
        max_steps: Newton steps per solve.
        max_backtracks: halvings of the step in the line search.
        max_regularisations: tenfold increases of ``mu`` in the curvature test.
        nonmonotone_window: iterates whose largest merit the equilibrium solve's Armijo
            tests compare with (module docstring); 1: the monotone tests. The implicit time
            step's own iteration (``jaxtube._dynamics.step_newton``) keeps the monotone test.
        linear_solver: ``"auto"`` (sparse KLU on the CPU for a model giving Hessian blocks
            and a KKT system of at least ``SPARSE_CROSSOVER`` unknowns, augmented where the
            model also gives constraint factors, else dense), ``"dense"``, ``"sparse"`` or
            ``"augmented"`` (``jaxtube._solver.kkt_linear``, ``kkt_augmented``).
    """

    rtol: float = 1e-10
    atol: float = 1e-12
    constraint_tol: float = 1e-11
    max_steps: int = eqx.field(static=True, default=60)
    max_backtracks: int = eqx.field(static=True, default=30)
    max_regularisations: int = eqx.field(static=True, default=12)
    nonmonotone_window: int = eqx.field(static=True, default=3)
    linear_solver: str = eqx.field(static=True, default="auto")


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


def _lagrangian_hessian(objective, hessian_fn, route, args, z, lam):
    """The Hessian of the Lagrangian in the route's form (dense matrix or flat block
    values): the model's (``hessian_fn``), or dense forward-over-reverse autodiff."""
    if hessian_fn is None:
        return route.hessian(jax.hessian(lambda zz: _lagrangian(objective, zz, lam, args)[0])(z))
    if isinstance(route, AugmentedSparseKKT):
        return route.hessian(hessian_fn(z, lam, args), hessian_fn.constraint_factors(z, args))
    return route.hessian(hessian_fn(z, lam, args))


def _kkt_at_solution(objective, hessian_fn, route, args, z, lam):
    """KKT matrix (route's form) at a solution ``(z, lam)``, for the implicit tangent: the
    Hessian and the constraint Jacobian with the floor regularisation ``MU_FLOOR``."""
    jacobian = (jax.jacrev(lambda zz: objective(zz, args)[1])(z) if route.needs_jacobian
                else None)
    return _floor_kkt(route, _lagrangian_hessian(objective, hessian_fn, route, args, z, lam),
                      jacobian)


def _floor_kkt(route, hessian, jacobian):
    """KKT matrix (route's form) of a Hessian and constraint Jacobian (``None`` on a route
    that does not form it) with the floor regularisation ``MU_FLOOR``."""
    h_scale = jnp.maximum(jnp.max(jnp.abs(route.hessian_diagonal(hessian))), 1e-300)
    j_scale = route.jacobian_scale(hessian, jacobian)
    mu = MU_FLOOR * h_scale
    return route.kkt(hessian, jacobian, mu, MU_FLOOR * j_scale**2 / h_scale)


def _newton(objective, hessian_fn, solver: NewtonKKT, args, z0, lam0):
    n = z0.shape[0]
    m = lam0.shape[0]
    k = jax.eval_shape(objective, z0, args)[0].shape[0]
    dtype = z0.dtype
    route = kkt_route(hessian_fn, solver.linear_solver, args, z0, lam0)

    def constraints_of(z):
        return objective(z, args)[1]

    def linearise(z, lam):
        """``(terms [k], c [m], part_grads [k, n], J^T lam [n], jacobian [m, n] or None)``:
        each energy term's gradient (``k`` reverse passes) and, for a route that needs it,
        the constraint Jacobian (``m`` reverse passes of the constraints alone), else
        ``J^T lam`` (one reverse pass). Two linearisations rather than one pulled back
        along all ``k + m`` cotangents: there every constraint's cotangent also travelled
        back through the energy (664 lines, every joint law), 22 ms against 7 ms per Newton
        step on the V3 kite (2026-12-02, idle 2-core CPU)."""
        parts, part_pullback = jax.vjp(lambda zz: objective(zz, args)[0], z)
        (part_grads,) = jax.vmap(part_pullback)(jnp.eye(k, dtype=dtype))
        c, constraint_pullback = jax.vjp(constraints_of, z)
        if not route.needs_jacobian:
            (jt_lam,) = constraint_pullback(lam)
            return parts, c, part_grads, jt_lam, None
        if m:
            (jacobian,) = jax.vmap(constraint_pullback)(jnp.eye(m, dtype=dtype))
        else:
            jacobian = jnp.zeros((0, n), dtype)
        return parts, c, part_grads, jacobian.T @ lam, jacobian

    def lagrangian_hessian(z, lam):
        return _lagrangian_hessian(objective, hessian_fn, route, args, z, lam)

    def merit(z, rho):
        terms, c = objective(z, args)
        return jnp.sum(terms) + rho * jnp.sum(jnp.abs(c))

    def newton_step(z, lam, rho, e, c, grad_e, jacobian, hessian, skip):
        """The regularised KKT solve: the :class:`PendingStep` from ``z`` (no solve where
        ``skip``: see :func:`jaxtube._solver.kkt_step.unless`)."""
        finite = all_finite(hessian)
        # Curvature test with growing regularisation (inertia-free).
        h_scale = jnp.maximum(jnp.max(jnp.abs(route.hessian_diagonal(hessian))), 1e-300)
        j_scale = route.jacobian_scale(hessian, jacobian)

        def solve_with(mu):
            return regularised_step(route, hessian, jacobian, grad_e, c, lam, mu,
                                    h_scale, j_scale)

        # One loop whose first pass is the floor regularisation, then 1e-8 h, growing
        # tenfold: the factorisation is compiled once (a first solve before the loop
        # would be a second copy of it in the program).
        def reg_cond(rc):
            _, ok, _, tries, _ = rc
            return (~ok) & (tries < solver.max_regularisations)

        def reg_body(rc):
            _, _, _, tries, mu = rc
            mu = jnp.where(tries < 0, MU_FLOOR * h_scale,
                           jnp.where(tries == 0, 1e-8 * h_scale, 10.0 * mu))
            sol, ok, factors = solve_with(mu)
            return sol, ok, factors, tries + 1, mu

        unsolved = jnp.zeros((n + m,), dtype)
        sol, _, factors, _, _ = jax.lax.while_loop(
            reg_cond, reg_body,
            (unsolved, skip, identity, jnp.full((), -1, jnp.int32), jnp.zeros((), dtype)))
        dz, lam_new = sol[:n], sol[n:]
        rho_new = jnp.maximum(rho, 2.0 * jnp.max(jnp.abs(lam_new), initial=0.0) + 1e-12)
        violation = jnp.sum(jnp.abs(c))
        return PendingStep(
            pending=jnp.ones((), bool), dz=dz, lam_new=lam_new, rho=rho_new,
            merit=e + rho_new * violation, slope=grad_e @ dz - rho_new * violation, c=c,
            jacobian_step=(jacobian @ dz if route.needs_jacobian else jnp.zeros((m,), dtype)),
            factors=factors, finite=finite & jnp.all(jnp.isfinite(dz)))

    def line_search(z, lam, trial, c_full, reference, skip):
        """After a refused full step: ``(z + alpha dz + alpha^2 s, lam + alpha (lam_new -
        lam), accepted)`` along the second-order correction ``s`` of curved constraints
        (kkt_step's docstring; ``s = 0`` without them), ``alpha = 1`` (where ``s != 0``),
        then ``1/2, 1/4, ...`` until the Armijo test against the ``reference`` merit passes
        (no trial where ``skip``: see :func:`jaxtube._solver.kkt_step.unless`)."""
        dz = trial.dz
        if m == 0:
            correction = jnp.zeros_like(dz)
        else:
            jacobian_step = (trial.jacobian_step if route.needs_jacobian
                             else jax.jvp(constraints_of, (z,), (dz,))[1])
            correction = second_order_correction(route, trial.factors, trial.c,
                                                 jacobian_step, dz, c_full)

        def ls_cond(lc):
            _, accepted, exponent = lc
            return (~accepted) & (exponent < solver.max_backtracks)

        def ls_body(lc):
            _, _, exponent = lc
            exponent = exponent + 1
            alpha = 0.5 ** exponent.astype(dtype)
            accepted = (merit(z + alpha * dz + alpha**2 * correction, trial.rho)
                        <= reference + 1e-4 * alpha * trial.slope)
            return alpha, accepted, exponent

        alpha, accepted, _ = jax.lax.while_loop(
            ls_cond, ls_body,
            (jnp.ones((), dtype), skip, first_trial_exponent(correction) - 1))
        return (z + alpha * dz + alpha**2 * correction, lam + alpha * (trial.lam_new - lam),
                accepted)

    def body(carry):
        z, lam, rho, step, _, _, res_g_last, res_c_last, trial, at_iterate, merits = carry
        # The point linearised: the proposed full step, or the iterate itself.
        pending = trial.pending
        point = jnp.where(pending, z + trial.dz, z)
        lam_point = jnp.where(pending, trial.lam_new, lam)
        parts, c, part_grads, jt_lam, jacobian = linearise(point, lam_point)
        grad_e = jnp.sum(part_grads, axis=0)
        e = jnp.sum(parts)
        res_g = jnp.max(jnp.abs(grad_e + jt_lam))
        res_c = jnp.max(jnp.abs(c), initial=0.0)

        # The proposed step: taken in full where it halves the KKT residual (no Maratos
        # effect or round-off stall near the solution) or passes the Armijo test on the
        # merit; otherwise the line search from z.
        full_ok = (res_g <= 0.5 * res_g_last) & (res_c <= jnp.maximum(0.5 * res_c_last,
                                                                      solver.constraint_tol))
        reference = merits.reference(trial.merit, trial.rho)
        armijo_full = (e + trial.rho * jnp.sum(jnp.abs(c)) <= reference + 1e-4 * trial.slope)
        full = pending & (full_ok | armijo_full)
        refused = pending & ~full
        z_searched, lam_searched, searched = unless(
            ~refused, lambda ops: line_search(*ops, ~refused),
            (z, lam, jnp.ones((), bool)), (z, lam, trial, c, reference))
        failed_search = refused & ~searched
        z = jnp.where(full, point, jnp.where(refused & searched, z_searched, z))
        lam = jnp.where(full, lam_point, jnp.where(refused & searched, lam_searched, lam))
        rho = jnp.where(pending, trial.rho, rho)
        step = step + (full | (refused & searched)).astype(jnp.int32)

        # At a linearised iterate (not one the line search just found): the stopping rule.
        # Its scale: the largest generalised force of any one energy term (internal
        # springs, applied loads, ...) or of the reactions J^T lambda. It does not involve
        # the tangent stiffness, and a self-equilibrated problem with zero reactions still
        # has the internal and load terms it balances.
        linearised = ~refused
        merits = merits.record(e, jnp.sum(jnp.abs(c)), linearised)
        # The Hessian at the linearised iterate: for its Newton step, and, at the solution,
        # for the implicit tangent (returned: the tangent's program needs no second copy).
        hessian = unless(refused, lambda ops: lagrangian_hessian(*ops), at_iterate[0],
                         (z, lam))
        at_iterate = (hessian, jax.tree.map(lambda new, kept: jnp.where(refused, kept, new),
                                            jacobian, at_iterate[1]))
        scale = jnp.maximum(jnp.max(jnp.abs(part_grads)), jnp.max(jnp.abs(jt_lam)))
        converged = (linearised & (res_g <= solver.rtol * scale + solver.atol)
                     & (res_c <= solver.constraint_tol))
        finite_residual = jnp.isfinite(res_g) & jnp.isfinite(res_c)
        # The next step (skipped once converged: the convergence test needs only the
        # gradient).
        take_step = linearised & ~converged & finite_residual & (step < solver.max_steps)
        trial = unless(~take_step, lambda ops: newton_step(*ops, ~take_step), no_trial,
                       (z, lam, rho, e, c, grad_e, jacobian, hessian))
        not_finite = (linearised & ~finite_residual) | (take_step & ~trial.finite)
        stop = converged | not_finite | failed_search
        code = jnp.where(converged, 0, jnp.where(not_finite, 3,
                                                 jnp.where(failed_search, 2, 1)))
        trial = eqx.tree_at(lambda t: t.pending, trial, trial.pending & ~stop)
        return (z, lam, rho, step, stop, code.astype(jnp.int32),
                jnp.where(linearised, res_g, res_g_last),
                jnp.where(linearised, res_c, res_c_last), trial, at_iterate, merits)

    def cond(carry):
        step, stop, trial = carry[3], carry[4], carry[8]
        return (~stop) & ((step < solver.max_steps) | trial.pending)

    # What a step not taken carries: zeros, and the identity's factors (XLA may execute the
    # line search's correction speculatively, and KLU stops the program on a singular
    # matrix).
    identity = route.identity_factors()
    zeros = lambda tree: jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), tree)  # noqa: E731
    no_hessian = zeros(jax.eval_shape(lagrangian_hessian, z0, lam0))
    no_jacobian = jnp.zeros((m, n), dtype) if route.needs_jacobian else None
    no_trial = zeros(jax.eval_shape(
        lambda: newton_step(z0, lam0, jnp.zeros((), dtype), jnp.zeros((), dtype),
                            jnp.zeros((m,), dtype), z0, no_jacobian, no_hessian,
                            jnp.zeros((), bool))))
    no_trial = eqx.tree_at(lambda t: t.factors, no_trial, identity)
    init = (z0, lam0, jnp.zeros((), dtype), jnp.zeros((), jnp.int32), jnp.zeros((), bool),
            jnp.ones((), jnp.int32), jnp.full((), jnp.inf, dtype), jnp.full((), jnp.inf, dtype),
            no_trial, (no_hessian, no_jacobian),
            RecentMerits.empty(solver.nonmonotone_window, dtype))
    z, lam, _, steps, _, code, res_g, res_c, _, at_iterate, _ = jax.lax.while_loop(
        cond, body, init)
    return z, lam, (code == 0, steps, code, res_g, res_c), at_iterate


@partial(jax.custom_jvp, nondiff_argnums=(0, 1, 2))
def _equilibrium(objective, hessian_fn, solver, args, z0, lam0):
    return _newton(objective, hessian_fn, solver, args, z0, lam0)


def _lagrangian(objective, z, lam, args):
    """``(E + lam . c, c)`` at ``z``."""
    terms, c = objective(z, args)
    return jnp.sum(terms) + jnp.dot(lam, c), c


def _kkt_residual(objective, z, lam, args):
    grad, c = jax.grad(lambda zz: _lagrangian(objective, zz, lam, args), has_aux=True)(z)
    return jnp.concatenate([grad, c])


def implicit_tangent(objective, route, args, args_dot, z, lam, kkt, stats):
    """The implicit function theorem's tangent ``(z_dot [n], lam_dot [m], stats_dot)`` of a
    KKT point ``(z, lam)``, ``kkt`` its KKT matrix (the route's form), ``stats`` the solve's."""
    _, residual_dot = jax.jvp(lambda a: _kkt_residual(objective, z, lam, a), (args,), (args_dot,))
    solution_dot = -route.solve(kkt, residual_dot)
    stats_dot = tuple(jnp.zeros_like(s) if jnp.issubdtype(s.dtype, jnp.inexact)
                      else np.zeros(s.shape, dtype=jax.dtypes.float0) for s in stats)
    n = z.shape[0]
    return solution_dot[:n], solution_dot[n:], stats_dot


@_equilibrium.defjvp
def _equilibrium_jvp(objective, hessian_fn, solver, primals, tangents):
    args, z0, lam0 = primals
    # The solve itself as the primitive it is (not re-traced under the tangents'
    # transformations: under ``jacfwd`` the Newton loops stay unbatched over the tangent
    # basis), then the tangent by the implicit function theorem.
    z, lam, stats, at_solution = _equilibrium(objective, hessian_fn, solver, args, z0, lam0)
    # The KKT matrix at the solution from the Hessian and constraint Jacobian of the solve's
    # last linearised iterate (the solution, where it converged), solved on the route of the
    # Newton iterations (chosen again here, at trace time, by the same static rule).
    route = kkt_route(hessian_fn, solver.linear_solver, args, z0, lam0)
    z_dot, lam_dot, stats_dot = implicit_tangent(objective, route, args, tangents[0], z, lam,
                                                 _floor_kkt(route, *at_solution), stats)
    at_solution_dot = jax.tree.map(jnp.zeros_like, at_solution)
    return ((z, lam, stats, at_solution), (z_dot, lam_dot, stats_dot, at_solution_dot))


def solve_equilibrium(
    objective,
    initial_state,
    args,
    solver: NewtonKKT = NewtonKKT(),
    initial_multipliers: Array | None = None,
    hessian=None,
    constraint_pattern=None,
    constraint_factors=None,
) -> EquilibriumResult:
    """Minimise an energy subject to equality constraints, both from one ``objective``.

    Args:
        objective: ``(state, args) -> (energy, constraints)``: the total potential energy
            [J], a scalar or a vector of terms ``[k]`` whose sum it is (each term's
            gradient sets the scale of the stopping rule, so pass internal and external
            terms separately: with a scalar, a problem whose loads balance internally has
            only ``atol``), and the equality constraints ``[m]`` (``m`` may be 0). One function
            for both, so that shared work (the structure's kinematics) is done once.
        initial_state: PyTree initial guess (e.g. the previous load step).
        args: PyTree of parameters; derivatives of the result w.r.t. it come from the
            implicit function theorem.
        solver: :class:`NewtonKKT` settings.
        initial_multipliers: ``[m]`` warm start for the multipliers.
        hessian: optional ``(state, multipliers, args) -> [n, n]`` or a list of blocks
            ``(rows, cols, values)`` (``jaxtube._solver.kkt_linear``), the exact Hessian of the
            Lagrangian ``E + multipliers . c`` w.r.t. the state flattened as by
            ``jax.flatten_util.ravel_pytree``; a model that knows its sparsity assembles it
            much faster than the default (dense forward-over-reverse autodiff), and blocks
            open the sparse KKT route.
        constraint_pattern: optional static ``(rows, cols)`` integer arrays: the entries of
            the constraint Jacobian ``dc/dstate`` (flattened state) that can be nonzero, a
            superset (used with ``hessian`` blocks on the sparse route; without it the
            Jacobian is stored dense there). A missed nonzero would give wrong steps.
        constraint_factors: optional ``(state, args) -> ConstraintFactors``: the constraint
            Jacobian in factored form ``C_z + C_w G^{-1} F`` (``jaxtube._solver.kkt_augmented``),
            for the augmented sparse route (used with ``hessian`` blocks; ``"auto"`` takes it
            on the CPU for systems of at least ``SPARSE_CROSSOVER`` unknowns). It must equal
            the Jacobian of the constraints; it is used for the linear systems only.

    Works under ``jit``, ``vmap`` (each member reports its own convergence), ``grad`` and
    ``jvp``. Requires float64 (docs/further/developer.md, "Float64"): float32 cannot reach
    Newton tolerances.
    """
    z0, unravel = ravel_pytree(initial_state)
    if z0.dtype != jnp.float64:
        raise TypeError(
            "jaxtube needs float64: enable it with jax.config.update('jax_enable_x64', True) "
            "before creating arrays (importing jaxtube does this unless JAXTUBE_NO_X64=1)."
        )

    def flat_objective(z, a):
        energy, constraints = objective(unravel(z), a)
        return jnp.reshape(energy, (-1,)), jnp.reshape(constraints, (-1,))

    flat_hessian = None
    if hessian is not None:
        def flat_hessian(z, lam, a):
            return hessian(unravel(z), lam, a)

        flat_hessian.constraint_pattern = constraint_pattern
        flat_hessian.constraint_factors = (
            None if constraint_factors is None
            else (lambda z, a: constraint_factors(unravel(z), a)))

    m = jax.eval_shape(flat_objective, z0, args)[1].shape[0]
    lam0 = jnp.zeros((m,), z0.dtype) if initial_multipliers is None else initial_multipliers
    z, lam, (converged, steps, code, res_g, res_c), _ = _equilibrium(
        flat_objective, flat_hessian, solver, args, z0, lam0
    )
    return EquilibriumResult(
        state=unravel(z), multipliers=lam, converged=converged, iterations=steps, result=code,
        residual=res_g, constraint_violation=res_c,
    )
