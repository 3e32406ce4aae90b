"""The KKT linear systems of the Newton solver: dense, or sparse from Hessian blocks (KLU).

**Hessian blocks (the interface a model implements).** A model that knows the sparsity of
its Lagrangian Hessian returns it from the ``hessian`` callable of ``solve_equilibrium`` as
a list of blocks ``(rows, cols, values)``:

- ``rows``, ``cols``: *static* integer numpy arrays of one shape (positions in the state
  flattened as by ``jax.flatten_util.ravel_pytree``), fixed for a structure;
- ``values``: a JAX float array of that same shape (e.g. ``[B, 6, 6]`` element Hessians of
  ``B`` joints over the 6 rotations of their two segments).

The Hessian is the sum of all blocks, entries at the same position added (blocks may
overlap: two joints share a segment). Its symmetric part is used (each entry counts half
at ``(r, c)`` and half at ``(c, r)``), as in the dense route. New element kinds (free point
nodes, tension-only lines, pulleys) add their own blocks; nothing here changes.

**Two routes, one system.** Each Newton iteration solves (``mu`` regularises the Hessian,
``delta`` the multipliers; ``solve_equilibrium`` explains both)::

    [H + mu I   J^T     ] [dz ]   [r_z]
    [J          -delta I] [lam] = [r_c]

- :class:`DenseKKT`: the matrix assembled dense (scatter-add of the blocks) and
  ``jnp.linalg.solve`` (LAPACK LU). Cost cubic in ``n + m``; the fastest for small
  structures and the only route off the CPU.
- :class:`SparseKKT`: KLU (``klujax``) on a pattern fixed once per structure: the blocks'
  positions, the diagonal, the constraint Jacobian (the model's static pattern where it
  gives one, ``solve_equilibrium``'s ``constraint_pattern``: a constraint touches only the
  unknowns on its nodes' tree paths; otherwise stored dense) and the multiplier diagonal,
  de-duplicated in numpy at trace time. The values are a scatter-add
  of the block values into that pattern (the dense matrix is never formed), and the
  symbolic analysis (fill-reducing ordering) is done once per pattern and reused by every
  factorisation, including the implicit-function-theorem tangent's.

- :class:`jaxtube._solver.kkt_augmented.AugmentedSparseKKT`: KLU on a larger, local system
  for a model that also gives its constraint Jacobian in factored form (tube structures:
  their constraints' rows are dense along tree paths, which fills the plain route's LU).

The route is chosen by ``NewtonKKT.linear_solver`` (``"auto"``: sparse on the CPU when the
model gives blocks and ``n + m >= SPARSE_CROSSOVER``, measured in
``experiments/bench_kkt.py``; augmented where the model gives constraint factors).

**klujax and JAX's global configuration.** ``import klujax`` sets ``jax_enable_x64`` and
``jax_platform_name = "cpu"`` for the whole process (klujax 0.5.2), which on a GPU machine
would pin every later computation to the CPU. It is imported here lazily, only when the
sparse route is taken, and both settings are restored right after (:func:`klujax_module`).
A symbolic analysis is a C++ handle baked into the compiled program: the Python object is
kept alive in a module-level cache for the life of the process (one per distinct pattern).
Only ``solve_with_symbol`` is used (it factorises and frees within the call); klujax's
``factor`` inside a loop would leak a numeric handle per iteration.
"""

from __future__ import annotations

import hashlib

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.linalg import lu_factor, lu_solve

#: Size ``n + m`` of the KKT system from which ``linear_solver="auto"`` takes the sparse
#: route (on the CPU, for a model that gives Hessian blocks). Measured crossover: see
#: ``experiments/bench_kkt.py`` and ``experiments/results/bench_kkt.txt``.
SPARSE_CROSSOVER = 120

#: Largest fraction of the KKT matrix's entries that the sparse pattern may hold for
#: ``linear_solver="auto"`` to keep the sparse route (above it: dense LAPACK).
SPARSE_MAX_FILL = 0.25

LINEAR_SOLVERS = ("auto", "dense", "sparse", "augmented")

_KLUJAX = None
_SYMBOLS: dict = {}  # pattern digest -> (Ai, Aj, KLUSymbolic), kept alive for the process


def klujax_module():
    """``klujax``, imported on first use with JAX's ``jax_platform_name`` and
    ``jax_enable_x64`` restored to what they were before the import."""
    global _KLUJAX
    if _KLUJAX is None:
        values = jax.config.values
        saved = {name: values[name] for name in ("jax_platform_name", "jax_enable_x64")}
        try:
            import klujax
        finally:
            for name, value in saved.items():
                jax.config.update(name, value)
        _KLUJAX = klujax
    return _KLUJAX


def is_blocks(hessian) -> bool:
    """Whether a ``hessian`` callable's output is a list of blocks (not a dense matrix)."""
    return isinstance(hessian, (list, tuple))


def _flat_blocks(blocks):
    rows = np.concatenate([np.asarray(r, dtype=np.int64).reshape(-1) for r, _, _ in blocks])
    cols = np.concatenate([np.asarray(c, dtype=np.int64).reshape(-1) for _, c, _ in blocks])
    values = jnp.concatenate([jnp.reshape(v, (-1,)) for _, _, v in blocks])
    return rows, cols, values


def dense_hessian(blocks, n: int):
    """The ``[n, n]`` matrix of a list of Hessian blocks (scatter-add), symmetrised."""
    if not is_blocks(blocks):
        return 0.5 * (blocks + blocks.T)
    rows, cols, values = _flat_blocks(blocks)
    matrix = jnp.zeros((n, n), values.dtype).at[rows, cols].add(values)
    return 0.5 * (matrix + matrix.T)


class DenseKKT:
    """The dense route: ``[n + m, n + m]`` matrix and LAPACK LU (``jnp.linalg.solve``).

    The Hessian it works with is a dense symmetric ``[n, n]`` matrix (:meth:`hessian`).
    """

    #: The Newton iteration forms the constraint Jacobian for this route's KKT matrix.
    needs_jacobian = True

    def __init__(self, n: int, m: int):
        self.n, self.m = n, m

    @staticmethod
    def jacobian_scale(hessian, jacobian):
        """The constraint Jacobian's largest entry (at least 1), the scale of the multipliers'
        regularisation ``delta`` (``jaxtube._solver.kkt_step``)."""
        return jnp.max(jnp.abs(jacobian), initial=1.0)

    def hessian(self, output):
        """The Hessian in this route's form from a ``hessian`` callable's output."""
        return dense_hessian(output, self.n)

    @staticmethod
    def hessian_diagonal(hessian):
        return jnp.diag(hessian)

    @staticmethod
    def hessian_times(hessian, vector):
        return hessian @ vector

    def kkt(self, hessian, jacobian, mu, delta):
        """KKT values for :meth:`solve`: here the dense matrix ``[n + m, n + m]``."""
        n, m, dtype = self.n, self.m, hessian.dtype
        top = jnp.concatenate([hessian + mu * jnp.eye(n, dtype=dtype), jacobian.T], axis=1)
        bottom = jnp.concatenate([jacobian, -delta * jnp.eye(m, dtype=dtype)], axis=1)
        return jnp.concatenate([top, bottom], axis=0)

    @staticmethod
    def solve(kkt, rhs):
        return jnp.linalg.solve(kkt, rhs)

    @staticmethod
    def factor(kkt):
        """LU factors of the KKT matrix (LAPACK ``getrf``), for :meth:`solve_factored`."""
        return lu_factor(kkt)

    def identity_factors(self):
        """:meth:`factor`'s output for the identity matrix (no factorisation): what a step
        not taken carries, so that a solve XLA executes speculatively is well posed."""
        size = self.n + self.m
        return jnp.eye(size), jnp.arange(size, dtype=jnp.int32)

    @staticmethod
    def solve_factored(factors, rhs):
        """``x`` with ``KKT x = rhs`` from :meth:`factor`'s LU factors (no refactorisation)."""
        return lu_solve(factors, rhs)


def jacobian_entries(n: int, m: int, jacobian_pattern=None) -> tuple[np.ndarray, np.ndarray]:
    """``(rows, cols)`` of the constraint Jacobian's stored entries: the model's static
    pattern (``solve_equilibrium``'s ``constraint_pattern``), or every entry (dense)."""
    if jacobian_pattern is not None:
        rows, cols = (np.asarray(a, dtype=np.int64).reshape(-1) for a in jacobian_pattern)
        return rows, cols
    return np.repeat(np.arange(m), n), np.tile(np.arange(n), m)


def kkt_pattern(blocks, n: int, m: int, jacobian_pattern=None):
    """The sparse route's KKT pattern from the blocks' static positions and the constraint
    Jacobian's (:func:`jacobian_entries`): ``keys`` (sorted row-major positions
    ``row * (n + m) + col`` of the distinct entries) and ``slot`` (for every contribution, in
    the order of :meth:`SparseKKT.kkt`, the entry it adds to)."""
    rows, cols, _ = _flat_blocks(blocks)
    diagonal = np.arange(n)
    jac_rows, jac_cols = jacobian_entries(n, m, jacobian_pattern)
    multiplier = n + np.arange(m)
    all_rows = np.concatenate([rows, cols, diagonal, n + jac_rows, jac_cols, multiplier])
    all_cols = np.concatenate([cols, rows, diagonal, jac_cols, n + jac_rows, multiplier])
    return np.unique(all_rows * (n + m) + all_cols, return_inverse=True)


class SparseKKT:
    """The sparse route: KLU on a static pattern built from the blocks' positions.

    Built once per structure (at trace time) from one output of the ``hessian`` callable
    (only its static ``rows`` and ``cols`` are used); the Hessian it works with is the
    flat vector of block values (:meth:`hessian`), in the order of those blocks.
    """

    needs_jacobian = True
    jacobian_scale = staticmethod(DenseKKT.jacobian_scale)

    def __init__(self, blocks, n: int, m: int, jacobian_pattern=None):
        self.klujax = klujax_module()
        self.n, self.m = n, m
        rows, cols, _ = _flat_blocks(blocks)
        self.block_rows, self.block_cols = rows, cols
        self.on_diagonal = np.flatnonzero(rows == cols)
        self.jac_rows, self.jac_cols = jacobian_entries(n, m, jacobian_pattern)
        size = n + m
        self._set_pattern(*kkt_pattern(blocks, n, m, jacobian_pattern), size)

    def _set_pattern(self, keys, slot, size: int) -> None:
        """The KLU pattern ``(Ai, Aj)`` of the distinct row-major ``keys`` of a ``size``-square
        matrix, each contribution's ``slot`` in it, and its symbolic analysis (done once
        per pattern in the process and kept alive in ``_SYMBOLS``)."""
        self.slot = slot.astype(np.int32).reshape(-1)
        self.nnz = int(keys.size)
        self.Ai = (keys // size).astype(np.int32)
        self.Aj = (keys % size).astype(np.int32)
        digest = hashlib.sha1(self.Ai.tobytes() + self.Aj.tobytes()
                              + np.int64(size).tobytes()).hexdigest()
        if digest not in _SYMBOLS:
            with jax.ensure_compile_time_eval():
                symbol = self.klujax.analyze(self.Ai, self.Aj, size)
            _SYMBOLS[digest] = (self.Ai, self.Aj, symbol)
        self.symbol = _SYMBOLS[digest][2]

    def hessian(self, output):
        """The flat block values ``[nnz_blocks]`` of a ``hessian`` callable's output."""
        rows, cols, values = _flat_blocks(output)
        if not (np.array_equal(rows, self.block_rows) and np.array_equal(cols, self.block_cols)):
            raise ValueError("the hessian callable's block positions changed between calls; "
                             "they must be static for a structure.")
        return values

    def hessian_diagonal(self, values):
        return jnp.zeros((self.n,), values.dtype).at[self.block_rows[self.on_diagonal]].add(
            values[self.on_diagonal])

    def hessian_times(self, values, vector):
        """``H_sym @ vector`` from the blocks (the symmetric part, as the KKT matrix)."""
        forward = jax.ops.segment_sum(values * vector[self.block_cols], self.block_rows,
                                      self.n)
        backward = jax.ops.segment_sum(values * vector[self.block_rows], self.block_cols,
                                       self.n)
        return 0.5 * (forward + backward)

    def kkt(self, values, jacobian, mu, delta):
        """KKT values ``[nnz]`` on the pattern ``(Ai, Aj)`` (scatter-add of the blocks)."""
        dtype = values.dtype
        half = 0.5 * values
        jac = jacobian[self.jac_rows, self.jac_cols]
        contributions = jnp.concatenate([
            half, half, jnp.full((self.n,), mu, dtype), jac, jac,
            jnp.full((self.m,), -delta, dtype)])
        return jax.ops.segment_sum(contributions, self.slot, self.nnz)

    @staticmethod
    def factor(kkt):
        """The KKT values themselves: ``solve_with_symbol`` factorises and frees within one
        call (klujax's ``factor`` handle inside a loop would leak), so :meth:`solve_factored`
        refactorises numerically; the symbolic analysis is reused."""
        return kkt

    def solve_factored(self, factors, rhs):
        """``x`` with ``KKT x = rhs`` from :meth:`factor`'s output."""
        return self.solve(factors, rhs)

    def identity_factors(self):
        """KKT values of the identity on the pattern (it holds the whole diagonal): what a
        step not taken carries, so that a solve XLA executes speculatively does not stop the
        program on a singular matrix (KLU)."""
        return jnp.asarray(self.Ai == self.Aj, dtype=jnp.float64)

    def solve(self, kkt, rhs):
        """``x`` with ``KKT x = rhs`` for KKT values ``[nnz]`` and ``rhs [n + m]``.

        KLU's solve primitive is bound directly: klujax's ``solve_with_symbol`` sorts the
        pattern inside the program (``lexsort`` of ``Ai, Aj``, then a gather of the values),
        which XLA constant-folds at every call site (minutes of compilation for a whole
        kite's pattern of 10^5-10^6 entries) and repeats at run time. The pattern here is
        already in that order (``np.unique`` of row-major keys), so nothing is sorted. The
        primitive's own batching and differentiation rules apply (``vmap``, ``jvp``).
        """
        return self._klu_solve(kkt, rhs)

    def _klu_solve(self, values, rhs):
        """KLU's solve primitive on this route's pattern: ``x [size]`` with ``A x = rhs``."""
        x = self.klujax.solve_with_symbol_f64.bind(
            jnp.asarray(self.Ai), jnp.asarray(self.Aj), jnp.reshape(values, (1, -1)),
            jnp.reshape(rhs, (1, -1, 1)), jnp.asarray(self.symbol.raw, dtype=jnp.uint64))
        return jnp.reshape(x, jnp.shape(rhs))


def choose_route(linear_solver: str, blocks_given: bool, size: int,
                 pattern_entries: int = 0, factors_given: bool = False) -> str:
    """``"dense"``, ``"sparse"`` or ``"augmented"`` for a ``NewtonKKT.linear_solver`` setting,
    a KKT system of ``size`` unknowns whose sparse pattern (:func:`kkt_pattern`) has
    ``pattern_entries``; ``factors_given``: the model gives its constraint Jacobian in factored
    form (``jaxtube._solver.kkt_augmented``), which ``"auto"`` then prefers to ``"sparse"``."""
    if linear_solver not in LINEAR_SOLVERS:
        raise ValueError(f"NewtonKKT.linear_solver must be one of {LINEAR_SOLVERS}, got "
                         f"{linear_solver!r}.")
    if linear_solver == "dense":
        return "dense"
    on_cpu = jax.default_backend() == "cpu"
    if linear_solver == "augmented":
        if not (blocks_given and factors_given):
            raise ValueError("NewtonKKT(linear_solver='augmented') needs a model whose hessian "
                             "returns blocks and that gives constraint factors "
                             "(jaxtube._solver.kkt_augmented).")
        if not on_cpu:
            raise ValueError("NewtonKKT(linear_solver='augmented') runs on the CPU only (KLU); "
                             f"the default backend is {jax.default_backend()!r}.")
        return "augmented"
    if linear_solver == "sparse":
        if not blocks_given:
            raise ValueError("NewtonKKT(linear_solver='sparse') needs a model whose hessian "
                             "returns blocks (see jaxtube._solver.kkt_linear); this one returns a "
                             "dense matrix or none.")
        if not on_cpu:
            raise ValueError("NewtonKKT(linear_solver='sparse') runs on the CPU only (KLU); "
                             f"the default backend is {jax.default_backend()!r}.")
        return "sparse"
    # KLU has no dense kernels: a mostly dense pattern (a constraint Jacobian stored dense
    # because the model gave no pattern: many constraints on many unknowns) goes to LAPACK
    # (the V3 kite without its pattern: 554,757 entries, a third of its KKT matrix; dense
    # 1.9 s per Newton step against sparse 2.5-3.2 s on the same loaded machine, README).
    mostly_dense = pattern_entries > SPARSE_MAX_FILL * size**2
    if not (blocks_given and on_cpu and size >= SPARSE_CROSSOVER):
        return "dense"
    if factors_given:
        return "augmented"
    return "dense" if mostly_dense else "sparse"
