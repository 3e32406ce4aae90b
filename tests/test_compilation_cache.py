"""``jaxtube.enable_compilation_cache``: compiled programs land in the user's cache directory
(``$XDG_CACHE_HOME/jaxtube/xla``), ``JAXTUBE_NO_COMPILATION_CACHE=1`` turns it off, and the
directory stays below its bound (``max_bytes``). Each case runs in a fresh process (JAX
initialises its cache once per process)."""

import os
import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent("""
    import os
    import jax, jax.numpy as jnp
    import jaxtube as jt
    path = jt.enable_compilation_cache(min_compile_seconds=0.0,
                                       max_bytes=int(os.environ.get("TEST_MAX_BYTES", "-1")))
    print("PATH", path)
    if os.environ.get("TEST_PROGRAM", "a") == "a":
        print(float(jax.jit(lambda x: jnp.sin(x) * jnp.cos(2.0 * x))(0.3)))
    else:
        print(float(jax.jit(lambda x: jnp.cos(x) * jnp.sin(3.0 * x))(0.3)))
""")


def _run(tmp_path, **env):
    environment = {k: v for k, v in os.environ.items()
                   if k not in ("JAXTUBE_NO_COMPILATION_CACHE", "XDG_CACHE_HOME")}
    environment.update(XDG_CACHE_HOME=str(tmp_path / "cache"), **env)
    done = subprocess.run([sys.executable, "-c", SCRIPT], env=environment, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stdout


def _entries(directory):
    """``{name: bytes}`` of the cache's program entries (not JAX's access-time and lock
    files)."""
    return {p.name: p.stat().st_size for p in directory.iterdir()
            if p.is_file() and not p.name.endswith("-atime") and not p.name.startswith(".")}


def test_cache_directory_gets_the_compiled_program(tmp_path):
    out = _run(tmp_path)
    directory = tmp_path / "cache" / "jaxtube" / "xla"
    assert f"PATH {directory}" in out
    assert directory.is_dir() and any(directory.iterdir())


def test_opt_out_leaves_no_cache(tmp_path):
    out = _run(tmp_path, JAXTUBE_NO_COMPILATION_CACHE="1")
    assert "PATH None" in out
    # Only jaxtube's folder is checked: other libraries (matplotlib's font cache, imported
    # with jaxtube's figures) may use the same XDG cache home.
    assert not (tmp_path / "cache" / "jaxtube").exists()



def test_the_command_line_turns_the_cache_on_unless_told_not_to(monkeypatch, tmp_path):
    """``jaxtube`` enables the cache before it runs a subcommand, and ``--no-compilation-cache``
    skips it (here on a spec that does not exist: exit 2, nothing compiled)."""
    import jaxtube as jt
    from fitting._cli import main

    calls = []
    monkeypatch.setattr(jt, "enable_compilation_cache", lambda *a, **k: calls.append(a))
    missing = str(tmp_path / "missing.toml")
    assert main(["simulate", missing, "--out", str(tmp_path / "a")]) == 2
    assert len(calls) == 1
    assert main(["--no-compilation-cache", "simulate", missing,
                 "--out", str(tmp_path / "b")]) == 2
    assert len(calls) == 1


def test_the_cache_stays_below_its_bound(tmp_path):
    """Programs of the sparse KKT routes can never be served again (the KLU analysis'
    address is in them, ``jaxtube._compilation_cache``), so the directory is bounded: with
    room for one program, a second one evicts the least recently used first, here one
    written by an unbounded run (JAX's eviction failed on such entries until they were
    given access times)."""
    directory = tmp_path / "cache" / "jaxtube" / "xla"
    _run(tmp_path, TEST_PROGRAM="a")
    first = _entries(directory)
    assert len(first) == 1
    bound = int(1.5 * sum(first.values()))
    _run(tmp_path, TEST_PROGRAM="b", TEST_MAX_BYTES=str(bound))
    second = _entries(directory)
    assert len(second) == 1 and not set(second) & set(first)  # the first one evicted
    assert sum(second.values()) <= bound


def test_a_zero_bound_is_refused():
    import jaxtube as jt

    with pytest.raises(ValueError, match="max_bytes"):
        jt.enable_compilation_cache(max_bytes=0)
