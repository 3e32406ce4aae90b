"""One regularised Newton-KKT step and its second-order correction, for the iteration of
:mod:`jaxtube._solver.newton_kkt`; the proposed step it carries to the next pass
(:class:`PendingStep`), the recent merits its nonmonotone Armijo tests compare with
(:class:`RecentMerits`) and the skippable section it runs in (:func:`unless`).

**The regularised step.** With Hessian ``H``, constraint Jacobian ``J``, energy gradient
``g`` and constraints ``c``, the step ``dz`` and the new multipliers solve::

    [H + mu I   J^T     ] [dz     ]   [-g                 ]
    [J          -delta I] [lam_new] = [-c - delta lam     ]

``delta = (1e-10 + mu / h) j^2 / h`` (``h`` the largest diagonal entry of ``H``, ``j`` the
largest entry of ``J``) is a proximal term on the multipliers, ``-delta (lam_new - lam)``,
which vanishes at a solution and keeps a rank-deficient ``J`` (redundant constraints: an
inextensible straight tube between two pins) solvable. The step is accepted by the
inertia-free curvature test (Chiang & Zavala 2016) ``dz^T (H + mu I) dz >= 1e-10 h |dz|^2``;
otherwise the caller raises ``mu``.

**Second-order correction** (Nocedal & Wright 2006, *Numerical Optimization*, 2nd ed.,
section 15.4 and Algorithm 18.3). The step satisfies the linearised constraints
``c + J dz = 0``; on curved constraints (a point tied to a tube node, which moves on a sphere
as its segments rotate; a tip held by a displacement control) the full step leaves
``c(z + dz) = w``, a violation of second order in ``dz``. The l1 merit ``E + rho |c|_1``
then rejects steps whose energy decrease is real (the Maratos effect), far from the solution
too: on the TU Delft V3 kite the line search cut a good Newton step 16- to 32-fold because
the ties' curvature violation, times ``rho``, outweighed the energy decrease. The correction
``s`` is the least-change step, in the metric of the same KKT matrix, that removes ``w``::

    K [s; .] = [0; -w],      w = c(z + dz) - c - J dz,

and the line search runs along the curve ``z + alpha dz + alpha^2 s``, on which the
constraints are ``(1 - alpha) c + O(alpha^3 |dz|^3)`` (Nocedal & Wright's curvilinear
search), starting with the corrected full step ``z + dz + s`` (``alpha = 1``: their
Algorithm 18.3 tries it before any backtracking). On the V3 kite this cut the Newton steps
of the tip-load stages after the first from 69 to 36 (case 4) and from 55 to 34 (case 5).
It reuses the step's factorisation (dense LU; KLU refactorises: its symbolic analysis is
reused). For constraints linear in the state ``w = 0`` and ``s = 0`` exactly, so
such problems take the same iterates as without it.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array


def all_finite(tree):
    """Whether every entry of every array in ``tree`` is finite (a route's Hessian may be a
    matrix, a vector of block values, or a pair of them)."""
    return jnp.all(jnp.stack([jnp.all(jnp.isfinite(x)) for x in jax.tree.leaves(tree)]))


def regularised_step(route, hessian, jacobian, grad_e, c, lam, mu, h_scale, j_scale):
    """Solve the regularised KKT system at regularisation ``mu`` (see the module docstring).

    Args:
        route: ``DenseKKT`` or ``SparseKKT`` (``jaxtube._solver.kkt_linear``).
        hessian: the Hessian in the route's form. jacobian: ``[m, n]``.
        grad_e: energy gradient ``[n]``. c: constraints ``[m]``. lam: multipliers ``[m]``.
        mu, h_scale, j_scale: scalars (``h_scale`` > 0).

    Returns:
        ``(solution [n + m], curvature_ok, factors)``: ``solution`` is ``(dz, lam_new)``;
        ``factors`` the factorised KKT matrix for :func:`second_order_correction`.
    """
    n = grad_e.shape[0]
    delta = (1e-10 + mu / h_scale) * j_scale**2 / h_scale
    rhs = jnp.concatenate([-grad_e, -c - delta * lam])
    factors = route.factor(route.kkt(hessian, jacobian, mu, delta))
    sol = route.solve_factored(factors, rhs)
    dz = sol[:n]
    curvature = dz @ route.hessian_times(hessian, dz) + mu * (dz @ dz)
    ok = (curvature >= 1e-10 * h_scale * (dz @ dz)) & jnp.all(jnp.isfinite(sol))
    return sol, ok, factors


def first_trial_exponent(correction):
    """The exponent ``j`` of the line search's first trial ``alpha = 2^-j`` after a refused
    full step (int32): ``0``, the corrected full step ``z + dz + s``, where there is a
    correction; ``1`` without one (``alpha = 1`` would be the refused step again)."""
    return jnp.where(jnp.any(correction != 0.0), 0, 1).astype(jnp.int32)


def second_order_correction(route, factors, c, jacobian_times_step, dz, c_full):
    """The correction ``s [n]`` of the module docstring, from the constraints ``c`` at ``z``,
    their linearised change ``J dz`` (``jacobian_times_step [m]``), ``c_full`` at ``z + dz``
    and the step's ``factors``; zeros where it is not finite."""
    n = dz.shape[0]
    curvature_violation = c_full - c - jacobian_times_step
    rhs = jnp.concatenate([jnp.zeros((n,), dz.dtype), -curvature_violation])
    correction = route.solve_factored(factors, rhs)[:n]
    return jnp.where(jnp.all(jnp.isfinite(correction)), correction, 0.0)


def unless(skip, step, skipped, operands):
    """``skipped`` if ``skip`` else ``step(operands)``, written as a while-loop of at most one
    pass rather than ``lax.cond``.

    Under ``vmap`` a ``lax.cond`` with a batched predicate becomes a select that broadcasts
    every operand of both branches, constants included; klujax's solve refuses a batched
    sparsity pattern (``Ai cannot be vectorized``). A while-loop keeps its constants
    unbatched, and under ``vmap`` runs the step once for the members that need it, masked.

    Two things keep XLA from running the step when ``skip`` is set (measured with jax
    0.10.2 on the V3 kite: the line search's second-order correction, one KLU factorisation,
    ran on every pass of the Newton iteration, two fifths of a hang's time): the number of
    passes is data (``0`` or ``1``), so the compiler cannot bound the loop to one pass and
    turn it into straight-line code; and the step reads ``operands`` (any PyTree) through an
    optimisation barrier tied to the pass counter, so what it computes from values outside
    the loop is not loop-invariant and is not hoisted out of it. Either alone still ran the
    correction on every pass. A ``step`` must still be safe to run when skipped (its own
    loops start finished where it is given ``skip``, and every solve it may execute is well
    posed: a step not taken carries the identity's factors).
    """

    passes = jnp.where(skip, 0, 1).astype(jnp.int32)

    def body(carry):
        _, tied = jax.lax.optimization_barrier((carry[0], operands))
        return carry[0] + 1, step(tied)

    return jax.lax.while_loop(lambda carry: carry[0] < passes, body,
                              (jnp.zeros((), jnp.int32), skipped))[1]


class PendingStep(eqx.Module):
    """A Newton step proposed from the iterate ``z`` and not yet tested: the next pass of
    the iteration linearises at ``z + dz`` (with ``lam_new``), which serves both the
    full-step test and, when the step is taken, the next Newton step (one linearisation in
    the program, not a separate gradient for the test).

    Attributes:
        pending: a step is proposed. dz: ``[n]`` step (zeros when none). lam_new: ``[m]``.
        rho: penalty of the l1 merit. merit: its value at ``z``. slope: its directional
            derivative along ``dz``. c: constraints at ``z`` ``[m]``. jacobian_step: ``J dz``
            ``[m]`` (routes that form ``J``; zeros otherwise). factors: the step's KKT
            factors (second-order correction). finite: Hessian and step finite.
    """

    pending: Array
    dz: Array
    lam_new: Array
    rho: Array
    merit: Array
    slope: Array
    c: Array
    jacobian_step: Array
    factors: object
    finite: Array


class RecentMerits(eqx.Module):
    """The energy and constraint violation of the last few iterates, for the nonmonotone
    Armijo tests (Grippo, Lampariello & Lucidi 1986; :mod:`jaxtube._solver.newton_kkt`).

    Attributes:
        energy: ``[w]`` energies ``E`` (``-inf`` where no iterate is recorded yet).
        violation: ``[w]`` violations ``|c|_1``. Oldest first.
    """

    energy: Array
    violation: Array

    @classmethod
    def empty(cls, window: int, dtype) -> RecentMerits:
        """No iterate recorded, room for ``window`` (at least 1)."""
        if window < 1:
            raise ValueError(f"NewtonKKT.nonmonotone_window must be at least 1, got {window}")
        return cls(jnp.full((window,), -jnp.inf, dtype), jnp.zeros((window,), dtype))

    def record(self, energy, violation, where) -> RecentMerits:
        """These merits with an iterate's ``energy`` and ``violation`` added (the oldest
        dropped) where ``where``; unchanged otherwise."""
        pushed = RecentMerits(jnp.append(self.energy[1:], energy),
                              jnp.append(self.violation[1:], violation))
        return jax.tree.map(lambda new, old: jnp.where(where, new, old), pushed, self)

    def reference(self, merit, rho):
        """The merit a trial is compared with: the largest of ``merit`` (the current
        iterate's) and the recorded iterates' ``E + rho |c|_1`` at the penalty ``rho``."""
        return jnp.maximum(merit, jnp.max(self.energy + rho * self.violation))
