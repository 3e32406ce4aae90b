"""The sparse KKT route with the constraint Jacobian in factored form: no fill along tree paths.

**Why.** With segment rotations as unknowns a node's position is a sum over every segment on
its path from the root, so a constraint on a node (a bridle line's tie to the leading edge,
a support, a loop closure) has a Jacobian row that is dense along that whole path. KLU then
fills in what those rows couple: on the TU Delft V3 kite (``n = 984`` unknowns, ``m = 273``
constraints, 46,941 KKT entries) the LU factors hold 282,599 entries and one factorisation
takes about 20 ms (2026-12-02, idle 2-core CPU), the largest single cost of a Newton step.

**The factored form.** The constraints are affine in a few positions: the segment ends
``w`` ``[p = 3 S]`` and state entries such as the root and the point nodes; and the segment
ends follow the tree, ``w_s - w_parent(s) = step_s(z)`` (``w_parent`` the root position for a
segment on the ground). Linearised::

    J = C_z + C_w G^{-1} F,     G dw = F dz    (G: identity minus the parent, constant;
                                                F: each segment's d step_s / d(its unknowns)),

where ``C_z``, ``C_w`` are the constraints' (constant, sparse) derivatives. Keeping ``dw`` and
the multipliers ``nu`` of the tree relations as unknowns of the linear system gives the
augmented, symmetric system over ``(dz, dw, nu, lambda)``::

    [H + mu I   0     -F^T    C_z^T  ] [dz    ]   [r_z]
    [0          0      G^T    C_w^T  ] [dw    ] = [0  ]
    [-F         G      0      0      ] [nu    ]   [0  ]
    [C_z        C_w    0      -delta I] [lambda]   [r_c]

Eliminating ``dw`` and ``nu`` (``dw = G^{-1} F dz``, ``nu = -G^{-T} C_w^T lambda``) gives back
the KKT system of :mod:`jaxtube._solver.kkt_linear` exactly, with ``J`` as above, so the
iterates, the curvature test and the implicit tangent are those of the plain sparse route up
to round-off. Every row is now local (a segment, its parent, a node), the pattern is a tree
plus the lines' point graph, and KLU's fill stays near the pattern's size (measured in
``experiments/bench_kkt.py``). The textbook idea is Baraff's (1996) linear-time dynamics of
articulated bodies: keep the maximal coordinates in the linear system, not the reduced ones.

**The model's part.** ``solve_equilibrium(constraint_factors=...)``: a callable
``(state, args) -> ConstraintFactors`` whose ``tree`` blocks are the rows ``[-F  G]`` and whose
``constraint`` blocks are the rows ``[C_z  C_w]``, both over the columns ``(z [n], w [p])``,
with static positions and traced values (:class:`ConstraintFactors`). The model is
responsible for ``J = C_z + C_w G^{-1} F`` holding (``tests/test_sparse_kkt.py`` checks it
against the autodiff Jacobian at random states).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .kkt_linear import SparseKKT, _flat_blocks, klujax_module


@jax.tree_util.register_pytree_node_class
class ConstraintFactors:
    """The constraint Jacobian of a model in factored form (module docstring); a PyTree
    (``aux_count`` static), so a model can compute it inside ``jax.jit``.

    Attributes:
        aux_count: ``p``, the number of auxiliary unknowns ``w`` (and of tree relations).
        tree: blocks ``(rows [0, p), cols [0, n + p), values)``: the rows ``[-F  G]``.
        constraint: blocks ``(rows [0, m), cols [0, n + p), values)``: ``[C_z  C_w]``.

    Positions are static numpy integer arrays, values JAX arrays of the same shapes
    (the block interface of :mod:`jaxtube._solver.kkt_linear`); entries at one position add.
    """

    def __init__(self, aux_count: int, tree: list, constraint: list):
        self.aux_count = int(aux_count)
        self.tree = tree
        self.constraint = constraint

    def tree_flatten(self):
        return (self.tree, self.constraint), self.aux_count

    @classmethod
    def tree_unflatten(cls, aux_count, children):
        return cls(aux_count, *children)


class AugmentedSparseKKT(SparseKKT):
    """KLU on the augmented system of the module docstring, on a static pattern.

    Works with the Hessian as the pair ``(block values [nnz_H], factor values [nnz_F])``
    (:meth:`hessian`); the ``jacobian`` argument of :meth:`kkt` is not used (the factors
    stand for it). Right-hand sides and solutions are those of the plain system, ``[n + m]``.
    The Hessian's diagonal and products, the pattern's symbolic analysis and the KLU call
    are :class:`jaxtube._solver.kkt_linear.SparseKKT`'s.
    """

    #: The Newton iteration needs ``J^T lambda`` and ``J dz`` only (one reverse and one
    #: forward pass), not the ``m`` reverse passes of the matrix.
    needs_jacobian = False

    def __init__(self, blocks, factors: ConstraintFactors, n: int, m: int):
        self.klujax = klujax_module()
        self.n, self.m, self.p = n, m, factors.aux_count
        rows, cols, _ = _flat_blocks(blocks)
        self.block_rows, self.block_cols = rows, cols
        self.on_diagonal = np.flatnonzero(rows == cols)
        self.tree_rows, self.tree_cols, _ = _flat_blocks(factors.tree)
        self.cons_rows, self.cons_cols, _ = _flat_blocks(factors.constraint)
        p = self.p
        self.size = size = n + 2 * p + m
        nu = n + p + self.tree_rows
        lam = n + 2 * p + self.cons_rows
        all_rows = np.concatenate([rows, cols, np.arange(n), nu, self.tree_cols, lam,
                                   self.cons_cols, n + 2 * p + np.arange(m)])
        all_cols = np.concatenate([cols, rows, np.arange(n), self.tree_cols, nu, self.cons_cols,
                                   lam, n + 2 * p + np.arange(m)])
        self._set_pattern(*np.unique(all_rows * size + all_cols, return_inverse=True), size)

    def hessian(self, output, factors: ConstraintFactors):
        """``(Hessian block values, factor values)`` from a ``hessian`` callable's output and
        the model's :class:`ConstraintFactors` at the same state."""
        values = super().hessian(output)
        tree_rows, tree_cols, tree_values = _flat_blocks(factors.tree)
        cons_rows, cons_cols, cons_values = _flat_blocks(factors.constraint)
        if not (np.array_equal(tree_rows, self.tree_rows)
                and np.array_equal(tree_cols, self.tree_cols)
                and np.array_equal(cons_rows, self.cons_rows)
                and np.array_equal(cons_cols, self.cons_cols)):
            raise ValueError("the constraint factors' positions changed between calls; they "
                             "must be static for a structure.")
        return values, jnp.concatenate([tree_values, cons_values])

    def jacobian_scale(self, hessian, jacobian=None):
        """A scale of the constraint Jacobian's entries from the factors (at least 1):
        ``max|C| max(1, max|F|)``. An entry of ``J = C_z + C_w G^{-1} F`` is an entry of
        ``C_z``, or a sum of a few entries of ``C_w`` times an entry of one segment's ``F``
        (a tie: one; a loop closure: two), so this is the largest entry within a factor of
        about two; it sets the multipliers' regularisation, which vanishes at a solution."""
        del jacobian
        factor_values = hessian[1]
        tree = jnp.abs(factor_values[:self.tree_rows.size])
        cons = jnp.abs(factor_values[self.tree_rows.size:])
        return jnp.maximum(jnp.max(cons, initial=0.0) * jnp.max(tree, initial=1.0), 1.0)

    def hessian_diagonal(self, hessian):
        return super().hessian_diagonal(hessian[0])

    def hessian_times(self, hessian, vector):
        return super().hessian_times(hessian[0], vector)

    def kkt(self, hessian, jacobian, mu, delta):
        """Augmented KKT values ``[nnz]`` (``jacobian`` unused: the factors stand for it)."""
        del jacobian
        values, factor_values = hessian
        dtype = values.dtype
        half = 0.5 * values
        tree = factor_values[:self.tree_rows.size]
        cons = factor_values[self.tree_rows.size:]
        contributions = jnp.concatenate([
            half, half, jnp.full((self.n,), mu, dtype), tree, tree, cons, cons,
            jnp.full((self.m,), -delta, dtype)])
        return jax.ops.segment_sum(contributions, self.slot, self.nnz)

    def identity_factors(self):
        """KKT values of a nonsingular matrix on the pattern: ones on the diagonal of the
        ``z`` and ``lambda`` blocks and on ``G``'s diagonal (``[[0, I], [I, 0]]`` over
        ``(dw, nu)``: the pattern has no ``dw`` or ``nu`` diagonal), for what a step not
        taken carries (:meth:`SparseKKT.identity_factors`)."""
        n, p = self.n, self.p
        outer = (self.Ai == self.Aj) & ((self.Ai < n) | (self.Ai >= n + 2 * p))
        swap = (np.abs(self.Ai - self.Aj) == p) & (np.minimum(self.Ai, self.Aj) >= n) & (
            np.maximum(self.Ai, self.Aj) < n + 2 * p)
        return jnp.asarray(outer | swap, dtype=jnp.float64)

    def solve(self, kkt, rhs):
        """``x [n + m]`` of the plain KKT system, from the augmented one (zeros on the tree
        rows, the auxiliary unknowns dropped)."""
        n, p = self.n, self.p
        zeros = jnp.zeros(rhs.shape[:-1] + (2 * p,), rhs.dtype)
        x = self._klu_solve(kkt, jnp.concatenate([rhs[..., :n], zeros, rhs[..., n:]], axis=-1))
        return jnp.concatenate([x[..., :n], x[..., n + 2 * p:]], axis=-1)
