"""A persistent XLA compilation cache for jaxtube's programs, under the user's cache directory.

Compiling one structure's solver takes 10-40 s on a small CPU (README "Performance"); the
command line compiles the same programs on every run. :func:`enable_compilation_cache`
points JAX's persistent compilation cache at ``$XDG_CACHE_HOME/jaxtube/xla`` (or
``~/.cache/jaxtube/xla``), so a second run in a fresh process loads the compiled programs
instead of compiling them again. Entries are keyed by the program, the JAX/XLA versions and
the compile options, so a changed model or library cannot be served a stale program. Python
tracing is not cached (it is repeated on every run).

Opt out with the environment variable ``JAXTUBE_NO_COMPILATION_CACHE=1``. Call it before
the first compilation of the process: JAX initialises its cache on first use.
"""

from __future__ import annotations

import os
from pathlib import Path

import jax

#: Environment variable that turns the cache off (``1``).
OPT_OUT = "JAXTUBE_NO_COMPILATION_CACHE"


def default_cache_directory() -> Path:
    """``$XDG_CACHE_HOME/jaxtube/xla``, or ``~/.cache/jaxtube/xla`` without XDG_CACHE_HOME."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "jaxtube" / "xla"


def enable_compilation_cache(directory=None, min_compile_seconds: float = 1.0) -> Path | None:
    """Turn on JAX's persistent compilation cache for this process.

    Args:
        directory: where compiled programs are stored (created if missing); default
            :func:`default_cache_directory`.
        min_compile_seconds: programs that compile faster than this [s] are not stored.

    Returns:
        The cache directory, or ``None`` when ``JAXTUBE_NO_COMPILATION_CACHE=1`` is set
        (nothing is changed then).
    """
    if os.environ.get(OPT_OUT, "").strip() == "1":
        return None
    path = Path(directory) if directory is not None else default_cache_directory()
    path.mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", float(min_compile_seconds))
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return path
