"""Test configuration: float64 and strict dtype promotion for every test; single-threaded
XLA CPU kernels.

The suite runs on two worker processes (pytest-xdist, see pyproject.toml) on two-core
machines. XLA's default multi-threaded Eigen kernels then oversubscribe the cores: a small
dense solve that takes ~6 ms on one thread took 150-300 ms under that contention
(measured on this project's CI-sized machine, README "Performance"). The flags must be set
before JAX initialises its CPU backend, hence here, before ``import jax``; a value the
caller already put in ``XLA_FLAGS`` is kept.
"""

import os

_SINGLE_THREAD = "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"
if "xla_cpu_multi_thread_eigen" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " " + _SINGLE_THREAD).strip()
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")
