"""Traced programs stored on disk between runs: ``jax.jit`` without Python's tracing on a
second run.

A persistent compilation cache (``jaxtube._compilation_cache``) saves XLA's compilation,
not Python's tracing. The fit's residual-and-Jacobian program (``jacfwd`` of a ``vmap`` of a
``scan`` of the implicitly differentiated Newton solve) takes 6.6 s to trace and 0.7 s to
lower on every run of ``jaxtube demo`` (measured 2026-12-05, ``docs/performance.md``), about a
quarter of a second run. :func:`stored_jit` keeps each traced program as a serialised
``jax.export.Exported`` (StableHLO) under ``$XDG_CACHE_HOME/jaxtube/traced``; a later process
with the same code, the same static arguments and the same input shapes loads it instead of
tracing (a few milliseconds) and compiles it, from the compilation cache when that is on.
The command line stores the fit's program (``fit``, ``diagnose``, ``demo``: a second demo
21.2-22.5 s against 27.6 s) and ``simulate``'s load path (3.8-4.1 s against 5.3 s for the
bundled cantilever).

**What keys an entry** (sha256 of all of it):

- the function's module and qualified name (the module must hold it under that name, itself
  or decorated, without a closure: a lambda, a local function, a ``functools.partial`` or a
  closure is not stored, since its name does not say what it computes), and its static
  arguments in a canonical form (:func:`canonical`: dataclasses and ``equinox`` modules field
  by field, sets sorted, classes and functions by module and name); anything else (an object
  known only by its address) is not stored: the call is a plain ``jax.jit`` call;
- the input tree rebuilt with placeholder leaves, in the same canonical form (so a static
  field of an input node counts by value, not by how it prints), every leaf's shape, dtype
  and weak type;
- the source code: every ``.py`` file of ``jaxtube``, of the function's own top-level
  package, and of the package (or the module file) of every class or function met above,
  read at first use in the process. An edit to the model, the workbench or a user's own
  effect gives a new key in the next process; a file edited after the process read it
  stops the storing of its package for the rest of the process (what runs may no longer be
  what the file says; programs already in use in the process stay, as in ``jax.jit``'s
  cache). The key is computed once per input signature in a process. A class or function
  without a source file (``__main__``, a notebook cell) is not stored;
- the versions of JAX, jaxlib, equinox and NumPy, the backend and the JAX settings that
  change a trace (``_SETTINGS``).

Not in the key, so not to be relied on: module-level settings changed at run time (e.g.
``jaxtube._solver.kkt_linear``'s crossover), environment variables read while tracing, and
a set's iteration order (sets are keyed sorted; the program is the first process's).

**What is never stored.** Calls under a transformation (any input a tracer: the call is
``jax.jit``'s, differentiable as usual) or under ``jax.disable_jit``, inputs that are Python
scalars (their weak types would not survive), outputs whose tree would not come back the
same from the entry, and programs ``jax.export`` refuses: host callbacks, and custom calls
not guaranteed stable, such as klujax's KLU solves of the sparse KKT routes (they also bake
in an address that differs per process); those run from their one trace. An error raised
by the function while it is traced propagates (traced once). An unreadable entry
(truncated, another format) is written anew.

**Bounded.** After each write the directory is kept below ``max_bytes`` by deleting the
entries used least recently (a load touches its entry), and temporary files of killed
writers. Opt out with ``JAXTUBE_NO_COMPILATION_CACHE=1``, as for the compilation cache.
Entries are pickles read back by the same user: keep the directory private, as any cache.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib.metadata
import os
import pickle
import sys
import tempfile
import time
import types
from collections.abc import Callable
from pathlib import Path

import jax
import numpy as np

from ._compilation_cache import opted_in_directory, user_cache_directory

#: Default bound of the store [bytes] (least recently used entries go first).
DEFAULT_MAX_BYTES = 512 * 1024**2
_SUFFIX = ".jaxtube-traced"
_FORMAT = 1  # the entry's layout (a dict pickled), part of every key
_STORE: dict = {"directory": None, "max_bytes": DEFAULT_MAX_BYTES}


def default_store_directory() -> Path:
    """``$XDG_CACHE_HOME/jaxtube/traced``, or ``~/.cache/jaxtube/traced``."""
    return user_cache_directory("traced")


def enable_traced_program_store(directory=None,
                                max_bytes: int = DEFAULT_MAX_BYTES) -> Path | None:
    """Store the programs of :func:`stored_jit` functions under ``directory`` (default
    :func:`default_store_directory`) for later processes; ``max_bytes`` bounds it.

    Returns the directory, or ``None`` when ``JAXTUBE_NO_COMPILATION_CACHE=1`` is set
    (nothing is changed then). The ``jaxtube`` command turns it on with the compilation
    cache.
    """
    if int(max_bytes) <= 0:
        raise ValueError(f"enable_traced_program_store: max_bytes must be positive, got "
                         f"{max_bytes}.")
    path = opted_in_directory(directory, default_store_directory())
    if path is not None:
        _STORE.update(directory=path, max_bytes=int(max_bytes))
    return path


def disable_traced_program_store() -> None:
    """Stop storing and loading traced programs in this process."""
    _STORE["directory"] = None


class NotCanonical(Exception):
    """A static argument has no form that is the same in every process."""


class _Leaf:
    """Stands for an array leaf where an input tree is rebuilt to key its structure."""


_LEAF = _Leaf()


def _named(value, modules: set) -> str:
    """``module:qualname`` of a class or a module-level function (its module added to
    ``modules``); :class:`NotCanonical` for lambdas, locals, closures and anything its
    module does not hold under that name, itself or decorated (``functools.partial``,
    callable instances)."""
    qualname = getattr(value, "__qualname__", None)
    module = getattr(value, "__module__", None)
    if qualname is None or module is None or "<" in qualname:
        raise NotCanonical(repr(value))
    if getattr(value, "__closure__", None):
        raise NotCanonical(f"{module}.{qualname} closes over local values")
    found = sys.modules.get(module)
    for part in qualname.split("."):
        found = getattr(found, part, None)
    if found is not value and getattr(found, "__wrapped__", None) is not value:
        raise NotCanonical(f"{module}.{qualname} is not that module's attribute")
    modules.add(module)
    return f"{module}:{qualname}"


def canonical(value, modules: set) -> str:
    """A text for ``value`` that is the same in every process that has the same code, with
    the modules it names added to ``modules``; raises :class:`NotCanonical` otherwise.

    Sets are keyed sorted: a function whose program depends on a set's iteration order (which
    differs between processes) should not take one as a static argument."""
    if value is _LEAF:
        return "leaf"
    if value is None or isinstance(value, (bool, int, float, complex, str, bytes, np.generic)):
        return repr(value)
    if type(value) in (tuple, list):
        return f"{type(value).__name__}({','.join(canonical(v, modules) for v in value)})"
    if isinstance(value, tuple) and hasattr(value, "_fields"):  # a NamedTuple
        return f"{_named(type(value), modules)}({','.join(canonical(v, modules) for v in value)})"
    if type(value) in (set, frozenset):
        return f"set({','.join(sorted(canonical(v, modules) for v in value))})"
    if type(value) is dict:
        items = sorted((canonical(k, modules), canonical(v, modules)) for k, v in value.items())
        return f"dict({','.join(f'{k}:{v}' for k, v in items)})"
    if isinstance(value, np.ndarray):
        return f"array({value.dtype},{value.shape},{hashlib.sha256(value.tobytes()).hexdigest()})"
    if isinstance(value, (type, types.FunctionType, types.BuiltinFunctionType)):
        return _named(value, modules)
    if dataclasses.is_dataclass(value):  # equinox modules are dataclasses too
        fields = ",".join(f"{f.name}={canonical(getattr(value, f.name), modules)}"
                          for f in dataclasses.fields(value))
        return f"{_named(type(value), modules)}({fields})"
    raise NotCanonical(f"{type(value).__module__}.{type(value).__qualname__}")


_DIGESTS: dict = {}  # top-level module -> (files' (path, size, mtime), sha256 of them)


def _source_digest(module_name: str) -> str:
    """sha256 of every ``.py`` file of ``module_name``'s top-level package (or of its one
    file), read at its first use in this process (the code this process runs, as nearly as
    files can say). Raises :class:`NotCanonical` for a module without source files, and once
    any of its files changed size or modification time since (edited after import, whether
    reloaded or not: what runs may no longer be what the files say)."""
    top = module_name.split(".")[0]
    module = sys.modules.get(top)
    file = getattr(module, "__file__", None) if module is not None else None
    if module_name == "__main__" or file is None:
        raise NotCanonical(f"module {module_name} has no source file")
    root = Path(file).parent
    files = (sorted(root.rglob("*.py")) if Path(file).name == "__init__.py"
             else [Path(file)])
    try:
        signature = tuple((str(p), p.stat().st_size, p.stat().st_mtime_ns) for p in files)
    except OSError as error:  # a file removed while listing
        raise NotCanonical(str(error)) from None
    if top not in _DIGESTS:
        digest = hashlib.sha256()
        for path in files:
            digest.update(str(path.relative_to(root.parent)).encode())
            digest.update(path.read_bytes())
        _DIGESTS[top] = (signature, digest.hexdigest())
    known, digest = _DIGESTS[top]
    if signature != known:
        raise NotCanonical(f"the source files of {top} changed since this process read them")
    return digest


@functools.cache
def _library_versions() -> tuple[str, ...]:
    return tuple(importlib.metadata.version(n) for n in ("jax", "jaxlib", "equinox", "numpy"))


#: JAX settings that change what a trace produces (part of every key).
_SETTINGS = ("jax_enable_x64", "jax_numpy_dtype_promotion", "jax_numpy_rank_promotion",
             "jax_default_matmul_precision", "jax_default_prng_impl",
             "jax_threefry_partitionable", "jax_enable_custom_prng")


def _versions() -> str:
    values = jax.config.values
    return repr((_library_versions(), jax.default_backend(),
                 [values.get(s) for s in _SETTINGS], _FORMAT))


def _entry_key(fun: Callable, static: dict, treedef, leaves) -> str:
    """The entry's name (module docstring); :class:`NotCanonical` where there is none."""
    modules = {"jaxtube"}
    text = _named(fun, modules) + canonical(dict(static), modules)
    try:  # the input tree with its static fields, node by node (not its printed form)
        skeleton = jax.tree_util.tree_unflatten(treedef, [_LEAF] * len(leaves))
    except Exception as error:  # noqa: BLE001 - a node type that checks its leaves
        raise NotCanonical(f"input tree: {error}") from None
    text += canonical(skeleton, modules)
    text += repr([(np.shape(x), str(x.dtype), bool(getattr(x, "weak_type", False)))
                  for x in leaves])
    sources = sorted({_source_digest(m) for m in modules})
    return hashlib.sha256((text + repr(sources) + _versions()).encode()).hexdigest()


def _load(path: Path):
    """``(jitted call of the stored program, output tree)``, or ``None`` (no entry, or an
    unreadable one: it is written anew)."""
    try:
        entry = pickle.loads(path.read_bytes())
        exported = jax.export.deserialize(bytearray(entry["exported"]))
        out_tree = jax.tree_util.tree_structure(entry["skeleton"])
    except Exception:  # noqa: BLE001 - missing, truncated, another format, unreadable
        return None
    try:
        os.utime(path)  # most recently used (eviction)
    except OSError:
        pass
    return jax.jit(exported.call), out_tree


def _export(flat_program: Callable, out_tree: dict, leaves, path: Path):
    """Trace and export ``flat_program`` (a ``jax.jit`` of flat leaves to flat leaves, which
    records its output tree in ``out_tree``) and write the entry atomically. An error raised
    while tracing is the caller's and propagates. Where JAX refuses the export after tracing,
    or the output tree would not come back the same from the entry, ``flat_program`` itself
    serves the process (its trace is reused) and nothing is stored."""
    try:
        exported = jax.export.export(flat_program)(*leaves)
    except Exception:
        if "tree" not in out_tree:  # the function itself failed while being traced
            raise
        return flat_program, out_tree["tree"]  # host callbacks, unstable custom calls
    tree = out_tree["tree"]
    try:
        skeleton = jax.tree_util.tree_unflatten(tree, list(range(tree.num_leaves)))
        blob = pickle.dumps({"exported": exported.serialize(), "skeleton": skeleton})
        same_tree = jax.tree_util.tree_structure(pickle.loads(blob)["skeleton"]) == tree
    except Exception:  # noqa: BLE001 - no flatbuffers, an output node that cannot be pickled
        same_tree = False
    if not same_tree:  # (e.g. metadata compared by identity)
        return flat_program, tree
    try:
        handle, temporary = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        with os.fdopen(handle, "wb") as file:
            file.write(blob)
        os.replace(temporary, path)
        _evict(path.parent, _STORE["max_bytes"])
    except OSError:  # a read-only or full disk: run on without storing
        pass
    return jax.jit(exported.call), tree


def _evict(directory: Path, max_bytes: int) -> None:
    """Delete the least recently used entries until the directory holds ``max_bytes``, and
    temporary files over an hour old (a process killed while writing)."""
    entries = []
    for path in directory.glob("*"):
        try:
            info = path.stat()
        except OSError:  # removed by another process meanwhile
            continue
        if path.name.endswith(".tmp") and time.time() - info.st_mtime > 3600:
            path.unlink(missing_ok=True)
        elif path.name.endswith(_SUFFIX):
            entries.append((info.st_mtime_ns, info.st_size, path))
    entries.sort(key=lambda e: e[0])
    total = sum(size for _, size, _ in entries)
    for _, size, path in entries[:-1]:  # the newest (the entry just written) stays
        if total <= max_bytes:
            break
        path.unlink(missing_ok=True)
        total -= size


def stored_jit(fun: Callable, static_argnames: tuple[str, ...] = ()) -> Callable:
    """``jax.jit(fun, static_argnames=...)`` whose traced programs are kept on disk while
    :func:`enable_traced_program_store` is on (module docstring): a later process with the
    same code, static arguments and input shapes skips tracing. Static arguments are passed
    by keyword; the others are arrays (a call with a Python scalar, under a transformation,
    or with the store off is ``jax.jit``'s).

    The returned function also has ``compile(*args, **kwargs)``: the program for these
    arguments compiled ahead of time (``jax.jit(...).lower(...).compile()``), a callable
    taking the same arguments (to time compilation apart from the run)."""
    jitted = jax.jit(fun, static_argnames=static_argnames)
    # In this process, as jax.jit's own cache: (store, input tree, shapes, static arguments)
    # -> (call of the flat leaves, output tree), or None (jax.jit's call). The entry's key
    # (sources read, static arguments made canonical) is computed on a miss only.
    programs: dict = {}

    def stored_program(args, kwargs):
        """``(program of flat leaves, output tree, leaves, treedef)``, or ``None`` where the
        call is ``jax.jit``'s."""
        directory = _STORE["directory"]
        static = {k: kwargs[k] for k in static_argnames if k in kwargs}
        dynamic = {k: v for k, v in kwargs.items() if k not in static}
        leaves, treedef = jax.tree_util.tree_flatten((args, dynamic))
        if (directory is None or jax.config.values["jax_disable_jit"]
                or not all(isinstance(x, (jax.Array, np.ndarray))
                           and not isinstance(x, jax.core.Tracer) for x in leaves)):
            return None
        signature = (directory, treedef, tuple(sorted(static.items())),
                     tuple((np.shape(x), x.dtype, bool(getattr(x, "weak_type", False)))
                           for x in leaves))
        if signature not in programs:
            try:
                key = _entry_key(fun, static, treedef, leaves)
            except NotCanonical:
                programs[signature] = None
                return None
            path = Path(directory) / f"{key}{_SUFFIX}"
            out_tree = {}

            def run(*flat_leaves):
                a, k = jax.tree_util.tree_unflatten(treedef, flat_leaves)
                leaves_out, out_tree["tree"] = jax.tree_util.tree_flatten(
                    fun(*a, **k, **static))
                return leaves_out

            programs[signature] = _load(path) or _export(jax.jit(run), out_tree, leaves, path)
        found = programs[signature]
        return None if found is None else (*found, leaves, treedef)

    @functools.wraps(fun)
    def call(*args, **kwargs):
        found = stored_program(args, kwargs)
        if found is None:
            return jitted(*args, **kwargs)
        program, out_tree, leaves, _ = found
        return jax.tree_util.tree_unflatten(out_tree, program(*leaves))

    def compile_ahead(*args, **kwargs):
        found = stored_program(args, kwargs)
        if found is None:
            return jitted.lower(*args, **kwargs).compile()
        program, out_tree, leaves, treedef = found
        compiled = program.lower(*leaves).compile()

        def run_compiled(*a, **k):
            if any(name in static_argnames for name in k):
                raise TypeError(f"{fun.__name__}: compiled for its static arguments; pass "
                                f"only the others (got {sorted(k)})")
            flat, tree = jax.tree_util.tree_flatten((a, k))
            if tree != treedef:
                raise TypeError(f"{fun.__name__}: compiled for inputs {treedef}, got {tree}")
            return jax.tree_util.tree_unflatten(out_tree, compiled(*flat))

        return run_compiled

    call.jitted = jitted  # the plain ``jax.jit`` function (tests, benchmarks)
    call.compile = compile_ahead
    return call
