"""Which linear-algebra route a problem's Newton iteration takes: dense LAPACK, sparse KLU, or
KLU on the augmented system (:mod:`jaxtube._solver.kkt_linear`,
:mod:`jaxtube._solver.kkt_augmented`), chosen once at trace time from what the model gives
(Hessian blocks, a constraint pattern, constraint factors) and ``NewtonKKT.linear_solver``.
Shared by the equilibrium solver and the implicit time step."""

from __future__ import annotations

from .kkt_augmented import AugmentedSparseKKT
from .kkt_linear import DenseKKT, SparseKKT, choose_route, is_blocks, kkt_pattern


def kkt_route(hessian_fn, linear_solver: str, args, z0, lam0):
    """The route object for the problem at the flat start ``z0 [n]``, multipliers
    ``lam0 [m]``. A model's ``hessian_fn`` is traced once here for its static block positions
    (its values are unused, so the compiled program drops them); its ``constraint_pattern``
    attribute, where set, is the constraint Jacobian's static pattern, and its
    ``constraint_factors`` attribute opens the augmented route."""
    n, m = z0.shape[0], lam0.shape[0]
    blocks = None if hessian_fn is None else hessian_fn(z0, lam0, args)
    given = blocks is not None and is_blocks(blocks)
    pattern = getattr(hessian_fn, "constraint_pattern", None)
    factors = getattr(hessian_fn, "constraint_factors", None)
    factors_given = factors is not None and m > 0
    # The pattern is counted before any symbolic analysis: a mostly dense one goes dense.
    entries = (kkt_pattern(blocks, n, m, pattern)[0].size
               if given and not factors_given else 0)
    chosen = choose_route(linear_solver, given, n + m, entries, factors_given)
    if chosen == "augmented":
        return AugmentedSparseKKT(blocks, factors(z0, args), n, m)
    if chosen == "sparse":
        return SparseKKT(blocks, n, m, pattern)
    return DenseKKT(n, m)
