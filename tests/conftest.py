"""Test configuration: float64 and strict dtype promotion for every test; single-threaded
XLA CPU kernels and XLA's CPU fusion emitters off.

The suite runs on two worker processes (pytest-xdist, see pyproject.toml) on two-core
machines. XLA's default multi-threaded Eigen kernels then oversubscribe the cores: a small
dense solve that takes ~6 ms on one thread took 150-300 ms under that contention
(measured on this project's CI-sized machine, docs/performance.md). ``import jaxtube`` sets
that flag, and the fusion emitters' (half the compile time), in ``XLA_FLAGS``; XLA reads them
when JAX initialises its CPU backend, hence the import here, before anything runs on JAX.

Compiled programs go to a persistent cache shared by the workers (below).
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
# The command line turns on a persistent compilation cache in the user's cache directory; in
# the tests the cache below serves instead (tests/test_compilation_cache.py unsets this).
os.environ.setdefault("JAXTUBE_NO_COMPILATION_CACHE", "1")

import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import jax  # noqa: E402
import pytest  # noqa: E402

import jaxtube  # noqa: E402,F401  (its import-time settings: XLA_FLAGS, float64)

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")
# One persistent compilation cache for the two workers (and the experiment scripts they
# start): a model both need is compiled once. Entries are keyed by the compiled program, so
# a stale cache cannot serve changed code.
_CACHE = Path(os.environ.get("JAXTUBE_TEST_CACHE",
                             Path(tempfile.gettempdir()) / "jaxtube-test-compilation-cache"))
jax.config.update("jax_compilation_cache_dir", str(_CACHE))
jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)


# The fast tier (``python -m pytest -m "not slow"``, about 2 minutes warm) leaves out these
# files whole: each runs fits, diagnoses, subprocesses or study-sized solves, or compiles a
# large program of its own (a minute or more warm). A single slow test elsewhere carries
# ``@pytest.mark.slow`` itself. CI runs everything.
SLOW_FILES = frozenset({
    "test_diagnose_controls.py", "test_diagnose_designs.py", "test_diagnose_effects.py",
    "test_user_effect.py", "test_notebook.py", "test_experiments.py", "test_fitting.py",
    "test_effects.py", "test_sparse_kkt.py", "test_convergence_honesty.py",
    "test_v3_hanging.py", "test_v3_import.py", "test_kite_fem_hang.py",
    "test_shape_diagnose.py", "test_shape_smooth.py", "test_diagnosis_trust.py",
    "test_dynamics_time.py", "test_dynamics_cli.py", "test_sweep_cluster.py",
    "test_sweep.py", "test_members.py", "test_dynamics_modes.py", "test_gradients.py",
    "test_dead_load_drive.py",
})


# The two workers take whole files (``--dist loadfile``), each next file as one finishes, in
# collection order (``--no-loadscope-reorder``: xdist's default order, most tests first, put
# the few-test files that compile the most at the very end, where one worker ran them alone).
# These files run first, costliest first: their tests' seconds on a clean clone's CI run (empty
# compilation cache, the CI-sized machine; compile and run). Only the order depends on them.
COSTLIEST_FIRST = (
    "test_diagnose_controls.py", "test_dynamics_time.py", "test_experiments.py",
    "test_diagnose_designs.py", "test_user_effect.py", "test_sweep.py", "test_sparse_kkt.py",
    "test_notebook.py", "test_diagnosis_trust.py", "test_dynamics_modes.py",
    "test_diagnose_effects.py", "test_solver.py", "test_fitting.py", "test_v3_hanging.py",
    "test_shape_diagnose.py", "test_gradients.py", "test_effects.py", "test_dynamics_cli.py",
    "test_shape_smooth.py", "test_beam_references.py", "test_kite_fem_hang.py",
    "test_members.py", "test_dead_load_drive.py", "test_convergence_honesty.py",
    "test_hung_frame.py", "test_kite.py", "test_batched_newton.py", "test_v3_import.py",
)


def pytest_collection_modifyitems(config, items):
    slow = pytest.mark.slow
    for item in items:
        if item.path.name in SLOW_FILES:
            item.add_marker(slow)
    rank = {name: k for k, name in enumerate(COSTLIEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: file order kept
