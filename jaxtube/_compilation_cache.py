"""A persistent XLA compilation cache for jaxtube's programs, under the user's cache directory.

Compiling one structure's solver takes 10-40 s on a small CPU (``docs/performance.md``); the
command line compiles the same programs on every run. :func:`enable_compilation_cache`
points JAX's persistent compilation cache at ``$XDG_CACHE_HOME/jaxtube/xla`` (or
``~/.cache/jaxtube/xla``), so a second run in a fresh process loads the compiled programs
instead of compiling them again. Entries are keyed by the program, the JAX/XLA versions and
the compile options, so a changed model or library cannot be served a stale program. Python
tracing is not cached (it is repeated on every run).

Opt out with the environment variable ``JAXTUBE_NO_COMPILATION_CACHE=1``. Call it before
the first compilation of the process: JAX initialises its cache on first use.

**What it cannot serve, and why the cache is bounded.** The sparse KKT routes (KLU, taken
from ``n + m >= 120`` unknowns: kites, the V3 kite, long tubes) bake the address of KLU's
symbolic analysis into the compiled program (``jaxtube._solver.kkt_linear``). That address
differs from process to process, so such a program's cache key does too: it is compiled on
every run and each run stores one more entry that no later run can use (measured
2026-12-04: a 60-segment cantilever's dense-route program loaded in 3.5 s on the second
run instead of 17.1 s; its sparse-route program compiled in 14.6 and 17.4 s, one new
entry each). Analysing the pattern inside every solve instead (klujax's ``solve``, nothing
baked in) would make those programs cacheable but made the V3 hang 39 % slower (1.20 ->
1.66 s warm, same Newton steps), so it was not adopted. The directory is therefore kept
below ``max_bytes`` by JAX's least-recently-used eviction (it needs the ``filelock``
package, a dependency of jaxtube), so repeated runs of large structures cannot fill a
user's disk.
"""

from __future__ import annotations

import os
from pathlib import Path

import jax

#: Environment variable that turns the cache off (``1``).
OPT_OUT = "JAXTUBE_NO_COMPILATION_CACHE"


def user_cache_directory(name: str) -> Path:
    """``$XDG_CACHE_HOME/jaxtube/<name>``, or ``~/.cache/jaxtube/<name>`` without
    XDG_CACHE_HOME."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "jaxtube" / name


def default_cache_directory() -> Path:
    """``$XDG_CACHE_HOME/jaxtube/xla``, or ``~/.cache/jaxtube/xla`` without XDG_CACHE_HOME."""
    return user_cache_directory("xla")


def opted_in_directory(directory, default: Path) -> Path | None:
    """``directory`` (or ``default``), created; ``None`` when ``JAXTUBE_NO_COMPILATION_CACHE=1``
    is set (nothing is created then)."""
    if os.environ.get(OPT_OUT, "").strip() == "1":
        return None
    path = Path(directory) if directory is not None else default
    path.mkdir(parents=True, exist_ok=True)
    return path


#: Default bound of the cache directory [bytes] (least recently used entries go first).
DEFAULT_MAX_BYTES = 2 * 1024**3

try:  # JAX's names for an entry's file and its access-time file (its LRU eviction)
    from jax._src.lru_cache import _ATIME_SUFFIX, _CACHE_SUFFIX
except ImportError:  # pragma: no cover - a JAX that moved them
    _ATIME_SUFFIX, _CACHE_SUFFIX = "-atime", "-cache"


def _give_access_times(path: Path) -> None:
    """Give every entry written without a bound (no access-time file: an earlier, unbounded
    cache) its modification time as access time. JAX's eviction reads one per entry and,
    missing one, fails every later write to the directory (measured with jax 0.10.2)."""
    for entry in path.glob(f"*{_CACHE_SUFFIX}"):
        atime = entry.with_name(entry.name[: -len(_CACHE_SUFFIX)] + _ATIME_SUFFIX)
        if not atime.exists():
            atime.write_bytes(entry.stat().st_mtime_ns.to_bytes(8, "little"))


def enable_compilation_cache(directory=None, min_compile_seconds: float = 1.0,
                             max_bytes: int = DEFAULT_MAX_BYTES) -> Path | None:
    """Turn on JAX's persistent compilation cache for this process.

    Args:
        directory: where compiled programs are stored (created if missing); default
            :func:`default_cache_directory`.
        min_compile_seconds: programs that compile faster than this [s] are not stored.
        max_bytes: largest size of the directory [bytes]; beyond it the least recently used
            entries are deleted (JAX's ``jax_compilation_cache_max_size``); ``-1``: no bound.

    Returns:
        The cache directory, or ``None`` when ``JAXTUBE_NO_COMPILATION_CACHE=1`` is set
        (nothing is changed then).
    """
    max_bytes = int(max_bytes)
    if max_bytes == 0 or max_bytes < -1:
        raise ValueError(f"enable_compilation_cache: max_bytes must be positive or -1 (no "
                         f"bound), got {max_bytes}.")
    path = opted_in_directory(directory, default_cache_directory())
    if path is None:
        return None
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", float(min_compile_seconds))
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    if max_bytes != -1:
        _give_access_times(path)
    jax.config.update("jax_compilation_cache_max_size", max_bytes)
    return path
