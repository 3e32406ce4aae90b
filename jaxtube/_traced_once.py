"""Model functions traced once per structure and shape: ``jax.jit`` that keeps static outputs.

The solver calls the model's energy, Hessian and constraint factors many times while it is
traced (Newton body, line search, linearisations, the implicit tangent, the route's choice)
and under several transformations at once (``vmap`` over curves, ``jacfwd`` of a fit).
Called as plain Python, each call re-runs the model's Python code under every active
transformation. Wrapped in ``jax.jit``, the model is traced once per structure and input
shape, and the transformations act on its jaxpr (their rules are cached), which (with the
solver's own changes, ``jaxtube._solver.newton_kkt``) cut the trace of the fit's
residual-and-Jacobian program on the demo data from 35.7 s to about 6 s
(``docs/performance.md``).

A Hessian in block form returns *static* integer index arrays beside its traced values
(``jaxtube._solver.kkt_linear``); ``jax.jit`` would turn them into traced outputs.
:func:`jit_keeping_static_outputs` returns them as the NumPy arrays they are: they are
recorded when the function is traced and depend only on the static arguments and the
shapes of the inputs, which key the record.

``jax.jit``'s cache is keyed by the trace context too, which records "no mesh" in two ways
(unset, or the empty abstract mesh that some transformations set, e.g. inside a ``scan``
under ``vmap``). Both mean the same, but the Hessian of a path step was traced twice for
it; each call here sets the empty mesh explicitly where there is no mesh (a no-op in
meaning), so one trace serves both: the fit's trace fell further from 11 s to 6 s.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import numpy as np

#: The empty abstract mesh, set explicitly around every call (module docstring).
_NO_MESH = jax.sharding.AbstractMesh((), ())


def _signature(args, static: dict):
    """What the static outputs may depend on: the inputs' tree and shapes, the static
    arguments."""
    leaves, treedef = jax.tree_util.tree_flatten(args)
    return treedef, tuple(np.shape(leaf) for leaf in leaves), tuple(sorted(static.items()))


def jit_keeping_static_outputs(fun: Callable, static_argnames: tuple[str, ...]) -> Callable:
    """``jax.jit(fun, static_argnames=...)`` for a ``fun(*args, **static)`` whose output
    PyTree holds NumPy arrays (static: fixed by the static arguments and the input shapes)
    beside traced arrays. The NumPy leaves come back unchanged, the rest from the compiled
    function. ``args`` are positional and traced; ``static`` keyword-only and hashable."""
    recorded = {}

    def traced_part(*args, **static):
        leaves, treedef = jax.tree_util.tree_flatten(fun(*args, **static))
        fixed = tuple(leaf if isinstance(leaf, np.ndarray) else None for leaf in leaves)
        recorded[_signature(args, static)] = (treedef, fixed)
        return [leaf for leaf, kept in zip(leaves, fixed) if kept is None]

    compiled = jax.jit(traced_part, static_argnames=static_argnames)

    def call(*args, **static):
        if jax.sharding.get_abstract_mesh().empty:
            # No mesh: say so the same way everywhere (module docstring).
            with jax.sharding.use_abstract_mesh(_NO_MESH):
                traced = iter(compiled(*args, **static))
        else:
            traced = iter(compiled(*args, **static))
        treedef, fixed = recorded[_signature(args, static)]
        return jax.tree_util.tree_unflatten(
            treedef, [next(traced) if kept is None else kept for kept in fixed])

    call.__doc__ = fun.__doc__
    call.__wrapped__ = fun
    return call
