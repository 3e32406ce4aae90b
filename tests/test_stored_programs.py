"""Traced programs stored between runs (``jaxtube.stored_jit``, ``jaxtube._stored_programs``):
a later process loads them without tracing and gets the same results; anything whose program
cannot be stored, or whose key is not the same in every process, runs as ``jax.jit``."""

import dataclasses
import functools
import json
import os
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxtube as jt
from jaxtube import _stored_programs as stored

SUFFIX = ".jaxtube-traced"
TRACES = []


@dataclasses.dataclass(frozen=True)
class Settings:
    scale: float
    tags: frozenset = frozenset()


def model(x, y, *, settings):
    TRACES.append(settings)
    return {"value": x * settings.scale + jnp.sin(y), "total": jnp.sum(x)}


def with_callback(x, *, settings):
    TRACES.append(settings)
    jax.debug.callback(lambda v: None, x)
    return x * settings.scale


@pytest.fixture
def store(tmp_path, monkeypatch):
    monkeypatch.delenv("JAXTUBE_NO_COMPILATION_CACHE", raising=False)
    directory = jt.enable_traced_program_store(tmp_path / "traced")
    yield directory
    jt.disable_traced_program_store()


def entries(directory):
    return sorted(Path(directory).glob(f"*{SUFFIX}"))


def test_a_new_wrapper_loads_the_stored_program_without_tracing(store):
    x, y = jnp.arange(3.0), jnp.linspace(0.0, 1.0, 3)
    settings = Settings(2.0, frozenset({"b", "a"}))
    TRACES.clear()
    first = jt.stored_jit(model, static_argnames=("settings",))(x, y, settings=settings)
    assert len(TRACES) == 1 and len(entries(store)) == 1
    again = jt.stored_jit(model, static_argnames=("settings",))  # as in a fresh process
    second = again(x + 1.0, y, settings=settings)
    assert len(TRACES) == 1  # loaded, not traced
    want = jax.jit(model, static_argnames=("settings",))(x + 1.0, y, settings=settings)
    TRACES.clear()
    assert set(second) == {"value", "total"}
    np.testing.assert_array_equal(second["value"], want["value"])
    np.testing.assert_array_equal(second["total"], want["total"])
    np.testing.assert_array_equal(first["value"], x * 2.0 + jnp.sin(y))


def test_static_arguments_and_shapes_key_the_entries(store):
    x, y = jnp.arange(3.0), jnp.zeros(3)
    wrapped = jt.stored_jit(model, static_argnames=("settings",))
    wrapped(x, y, settings=Settings(2.0))
    wrapped(x, y, settings=Settings(3.0))
    wrapped(jnp.arange(4.0), jnp.zeros(4), settings=Settings(2.0))
    wrapped(x.astype(jnp.float32), y.astype(jnp.float32), settings=Settings(2.0))
    assert len(entries(store)) == 4
    wrapped(x, y, settings=Settings(2.0))
    assert len(entries(store)) == 4
    modules = set()
    assert (stored.canonical(Settings(1.0, frozenset({"x", "y", "z"})), modules)
            == stored.canonical(Settings(1.0, frozenset({"z", "y", "x"})), set()))
    assert __name__ in modules
    for not_canonical in (object(), lambda v: v, Settings(1.0, frozenset({object()}))):
        with pytest.raises(stored.NotCanonical):
            stored.canonical(not_canonical, set())


def test_transformations_scalars_and_unstorable_statics_run_as_jit(store):
    x, y = jnp.arange(3.0), jnp.ones(3)
    wrapped = jt.stored_jit(model, static_argnames=("settings",))
    settings = Settings(2.0)
    grad = jax.grad(lambda v: wrapped(v, y, settings=settings)["value"].sum())(x)
    np.testing.assert_allclose(grad, 2.0)
    batched = jax.vmap(lambda v: wrapped(v, y, settings=settings)["total"])(jnp.ones((4, 3)))
    np.testing.assert_allclose(batched, 3.0)
    np.testing.assert_allclose(wrapped(x, 0.5, settings=settings)["value"],
                               x * 2.0 + np.sin(0.5))
    local = Settings(2.0, frozenset({lambda v: v}))
    np.testing.assert_allclose(wrapped(x, y, settings=local)["total"], 3.0)
    assert entries(store) == []


def test_a_program_jax_cannot_export_runs_from_its_one_trace(store):
    x = jnp.arange(3.0)
    wrapped = jt.stored_jit(with_callback, static_argnames=("settings",))
    TRACES.clear()
    for _ in range(3):
        np.testing.assert_allclose(wrapped(x, settings=Settings(2.0)), 2.0 * x)
    assert len(TRACES) == 1 and entries(store) == []  # traced once, nothing stored
    TRACES.clear()


def test_an_unreadable_entry_is_written_anew_and_the_store_is_bounded(store):
    x, y = jnp.arange(3.0), jnp.zeros(3)
    jt.stored_jit(model, static_argnames=("settings",))(x, y, settings=Settings(2.0))
    (entry,) = entries(store)
    size = entry.stat().st_size
    entry.write_bytes(b"not a stored program")
    out = jt.stored_jit(model, static_argnames=("settings",))(x, y, settings=Settings(2.0))
    np.testing.assert_allclose(out["value"], 2.0 * x)
    assert entry.stat().st_size == size  # rewritten
    # Bounded: room for about two entries; the least recently used go first.
    jt.enable_traced_program_store(store, max_bytes=int(2.5 * size))
    wrapped = jt.stored_jit(model, static_argnames=("settings",))
    for scale in (3.0, 4.0, 5.0):
        wrapped(x, y, settings=Settings(scale))
    kept = entries(store)
    assert len(kept) == 2 and entry not in kept
    assert sum(p.stat().st_size for p in kept) <= int(2.5 * size)


def test_opting_out_leaves_the_store_off(tmp_path, monkeypatch):
    monkeypatch.setenv("JAXTUBE_NO_COMPILATION_CACHE", "1")
    assert jt.enable_traced_program_store(tmp_path / "traced") is None
    assert not (tmp_path / "traced").exists()
    with pytest.raises(ValueError, match="max_bytes"):
        jt.enable_traced_program_store(tmp_path / "traced", max_bytes=0)


USER_MODULE = """
import dataclasses
import jax.numpy as jnp

TRACED = []

@dataclasses.dataclass(frozen=True)
class Stiffness:
    factor: float
    names: frozenset

def response(x, *, stiffness):
    TRACED.append(1)
    return (x * stiffness.factor + {offset}, jnp.cos(x))
"""

RUN = """
import json, sys
import jax.numpy as jnp
import jaxtube as jt
sys.path.insert(0, sys.argv[1])
import user_model
jt.enable_traced_program_store(sys.argv[2])
f = jt.stored_jit(user_model.response, static_argnames=("stiffness",))
out = f(jnp.linspace(0.0, 1.0, 5),
        stiffness=user_model.Stiffness(3.0, frozenset({"leading_edge", "strut", "tip"})))
print(json.dumps({"traced": len(user_model.TRACED), "out": [o.tolist() for o in out]}))
"""


def test_a_second_process_loads_it_and_an_edited_module_is_traced_again(tmp_path):
    """Fresh processes with different hash seeds (a frozenset static argument): the second
    loads the first's program; after the user's module is edited, it is traced again."""
    (tmp_path / "user_model.py").write_text(USER_MODULE.format(offset="1.0"))
    (tmp_path / "run.py").write_text(RUN)
    env = {k: v for k, v in os.environ.items() if k != "JAXTUBE_NO_COMPILATION_CACHE"}

    def run(seed):
        result = subprocess.run(
            [sys.executable, str(tmp_path / "run.py"), str(tmp_path), str(tmp_path / "traced")],
            env={**env, "PYTHONHASHSEED": str(seed)}, capture_output=True, text=True,
            timeout=300, check=True)
        return json.loads(result.stdout.strip().splitlines()[-1])

    first, second = run(1), run(2)
    assert (first["traced"], second["traced"]) == (1, 0)
    assert first["out"] == second["out"]
    np.testing.assert_allclose(first["out"][0], np.linspace(0.0, 1.0, 5) * 3.0 + 1.0)
    (tmp_path / "user_model.py").write_text(USER_MODULE.format(offset="2.0"))
    edited = run(3)
    assert edited["traced"] == 1
    np.testing.assert_allclose(edited["out"][0], np.linspace(0.0, 1.0, 5) * 3.0 + 2.0)
    assert len(entries(tmp_path / "traced")) == 2


@pytest.mark.parametrize("store_on", [True, False])
def test_compiled_ahead_of_time_runs_the_same_program(store_on, tmp_path, monkeypatch):
    """``stored_jit(...).compile(...)`` (the command line times compilation apart): stored
    or not, a callable of the same arguments with ``jax.jit``'s results; with the store on,
    a new wrapper compiles the loaded program without tracing."""
    monkeypatch.delenv("JAXTUBE_NO_COMPILATION_CACHE", raising=False)
    if store_on:
        jt.enable_traced_program_store(tmp_path)
    try:
        x, y = jnp.arange(3.0), jnp.ones(3)
        TRACES.clear()
        compiled = jt.stored_jit(model, static_argnames=("settings",)).compile(
            x, y, settings=Settings(4.0))
        again = jt.stored_jit(model, static_argnames=("settings",)).compile(
            x, y, settings=Settings(4.0))
        if store_on:  # the second loaded (without the store, JAX's own cache serves it)
            assert len(TRACES) == 1
        for program in (compiled, again):
            out = program(x + 1.0, y)
            np.testing.assert_array_equal(out["value"], (x + 1.0) * 4.0 + jnp.sin(y))
        assert len(entries(tmp_path)) == (1 if store_on else 0)
    finally:
        jt.disable_traced_program_store()
        TRACES.clear()


def failing(x, *, settings):
    TRACES.append(settings)
    raise ValueError("the model's own error")


@dataclasses.dataclass(frozen=True)
class Hidden:
    scale: float = dataclasses.field(repr=False)  # printed alike for every scale


@dataclasses.dataclass(frozen=True)
class Holder:
    x: object
    hidden: Hidden  # the node's static metadata


jax.tree_util.register_pytree_node(
    Holder, lambda h: ((h.x,), h.hidden), lambda hidden, children: Holder(children[0], hidden))


def with_static_input(holder):
    return holder.x * holder.hidden.scale


def _times(k):
    def decorate(f):
        @functools.wraps(f)
        def wrapper(v):
            return f(v) * k
        return wrapper
    return decorate


@_times(2.0)
def doubled(v):
    return v  # a module-level closure: its name alone does not say what it computes


def test_what_is_never_stored_runs_as_jit(store):
    """Closures and partials (their values are not in the key), a module edited since it
    was read, ``jax.disable_jit``: each runs as ``jax.jit``, right, and nothing is stored."""
    x, y = jnp.arange(3.0), jnp.zeros(3)

    def make(k):
        def scaled(v):
            return v * k
        return jt.stored_jit(scaled)

    np.testing.assert_allclose(make(2.0)(x), 2.0 * x)
    np.testing.assert_allclose(make(3.0)(x), 3.0 * x)
    np.testing.assert_allclose(jt.stored_jit(doubled)(x), 2.0 * x)
    partial = jt.stored_jit(functools.partial(model, settings=Settings(5.0)))
    np.testing.assert_allclose(partial(x, y)["value"], 5.0 * x)
    with jax.disable_jit():
        plain = jt.stored_jit(model, static_argnames=("settings",))
        np.testing.assert_allclose(plain(x, y, settings=Settings(6.0))["value"], 6.0 * x)
    assert entries(store) == []
    # A module whose file changed after this process read it: no longer stored.
    module_dir = store.parent / "edited"
    module_dir.mkdir()
    (module_dir / "edited_model.py").write_text("def f(x):\n    return x * 1.0\n")
    sys.path.insert(0, str(module_dir))
    try:
        edited = __import__("edited_model")
        jt.stored_jit(edited.f)(x)
        assert len(entries(store)) == 1
        (module_dir / "edited_model.py").write_text("def f(x):\n    return x * 2.0  # new\n")
        np.testing.assert_allclose(jt.stored_jit(edited.f)(jnp.arange(4.0)), jnp.arange(4.0))
        assert len(entries(store)) == 1
    finally:
        sys.path.remove(str(module_dir))
        sys.modules.pop("edited_model", None)


def test_static_fields_of_inputs_key_entries_and_errors_propagate_once(store):
    """Input trees differing only in a static field (printed alike) get their own entries;
    the model's own error while tracing propagates, traced once; ``compile()`` refuses the
    static arguments at the call."""
    x = jnp.arange(3.0)
    wrapped = jt.stored_jit(with_static_input)
    np.testing.assert_allclose(wrapped(Holder(x, Hidden(2.0))), 2.0 * x)
    np.testing.assert_allclose(wrapped(Holder(x, Hidden(3.0))), 3.0 * x)
    assert len(entries(store)) == 2
    TRACES.clear()
    with pytest.raises(ValueError, match="the model's own error"):
        jt.stored_jit(failing, static_argnames=("settings",))(x, settings=Settings(1.0))
    assert len(TRACES) == 1
    TRACES.clear()
    compiled = jt.stored_jit(model, static_argnames=("settings",)).compile(
        x, x, settings=Settings(2.0))
    with pytest.raises(TypeError, match="static"):
        compiled(x, x, settings=Settings(3.0))
    with pytest.raises(TypeError, match="compiled for inputs"):
        compiled(x, (x,))
