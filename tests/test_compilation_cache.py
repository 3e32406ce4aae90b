"""``jaxtube.enable_compilation_cache``: compiled programs land in the user's cache directory
(``$XDG_CACHE_HOME/jaxtube/xla``), and ``JAXTUBE_NO_COMPILATION_CACHE=1`` turns it off.
Each case runs in a fresh process (JAX initialises its cache once per process)."""

import os
import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent("""
    import jax, jax.numpy as jnp
    import jaxtube as jt
    path = jt.enable_compilation_cache(min_compile_seconds=0.0)
    print("PATH", path)
    print(float(jax.jit(lambda x: jnp.sin(x) * jnp.cos(2.0 * x))(0.3)))
""")


def _run(tmp_path, **env):
    environment = {k: v for k, v in os.environ.items()
                   if k not in ("JAXTUBE_NO_COMPILATION_CACHE", "XDG_CACHE_HOME")}
    environment.update(XDG_CACHE_HOME=str(tmp_path / "cache"), **env)
    done = subprocess.run([sys.executable, "-c", SCRIPT], env=environment, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stdout


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
