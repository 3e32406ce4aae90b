"""Import-time settings of JAX that jaxtube needs, applied once, before anything runs on JAX.

Threads: single-threaded XLA CPU (Eigen) kernels unless the user chose: this package's
programs are many small dense operations, for which intra-op threads only add contention;
on 2-core machines the default threads made kite solves 16x and diagnoses ~4x slower
(README, "Threads"). XLA reads the flag when its CPU backend starts, so it takes effect
only if JAX has not run anything yet. Opt out with ``JAXTUBE_XLA_THREADS=1``, or set
``--xla_cpu_multi_thread_eigen`` in ``XLA_FLAGS`` yourself.

Float64: Newton tolerances need double precision, so ``jax_enable_x64`` is turned on
(README, "Float64"). ``JAXTUBE_NO_X64=1`` keeps JAX's default; solves then raise a clear
``TypeError`` instead of silently failing in float32.

``jaxtube/__init__.py`` imports this module first, so the settings hold before any other
jaxtube module imports JAX.
"""

import os

if ("xla_cpu_multi_thread_eigen" not in os.environ.get("XLA_FLAGS", "")
        and os.environ.get("JAXTUBE_XLA_THREADS", "0") in ("", "0")):
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "")
                               + " --xla_cpu_multi_thread_eigen=false").strip()

import jax  # noqa: E402  (after XLA_FLAGS: the flag must be set before JAX starts)

if os.environ.get("JAXTUBE_NO_X64", "0") in ("", "0"):
    jax.config.update("jax_enable_x64", True)
