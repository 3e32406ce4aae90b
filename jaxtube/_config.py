"""Import-time settings of JAX that jaxtube needs, applied once, before anything runs on JAX.

Threads: single-threaded XLA CPU (Eigen) kernels unless the user chose: this package's
programs are many small dense operations, for which intra-op threads only add contention; on
2-core machines the default threads made kite solves 16x and diagnoses ~4x slower
(docs/further/developer.md, "Threads"). XLA reads the flag when its CPU backend starts, so
it takes effect only if JAX has not run anything yet. Opt out with
``JAXTUBE_XLA_THREADS=1``, or set ``--xla_cpu_multi_thread_eigen`` in ``XLA_FLAGS``
yourself.

Float64: Newton tolerances need double precision, so ``jax_enable_x64`` is turned on
(docs/further/developer.md, "Float64"). ``JAXTUBE_NO_X64=1`` keeps JAX's default; solves
then raise a clear ``TypeError`` instead of silently failing in float32.

Compilation: XLA's CPU backend compiles each fusion with its MLIR fusion emitters by default;
on this package's programs they take about half of the compile time and make the programs no
faster, so jaxtube turns them off (``--xla_cpu_use_fusion_emitters=false``; compile CPU time
of the solve, gradient and fit programs 45-50 % lower, ``python -m experiments.bench_compile``,
docs/performance.md). Set only for the jaxlib versions it was measured on (0.7.2 to 0.10;
XLA stops a process at an unknown flag), and unless ``XLA_FLAGS`` already names the flag or
``JAXTUBE_XLA_FUSION_EMITTERS=1``.

CPU devices: ``JAXTUBE_CPU_DEVICES=N`` (or ``auto``: the CPUs this process may run on) adds
``--xla_force_host_platform_device_count=N`` unless ``XLA_FLAGS`` already sets it, so that
``jaxtube.map_members`` can split independent solves over the cores (docs/guides/solver.md,
"Many solves at once"). Off by default: with several devices ``fitting.sweep`` and anything
else that shards over ``jax.devices()`` use them all.

``jaxtube/__init__.py`` imports this module first, so the settings hold before any other
jaxtube module imports JAX.
"""

import os
from importlib.metadata import PackageNotFoundError, version

if ("xla_cpu_multi_thread_eigen" not in os.environ.get("XLA_FLAGS", "")
        and os.environ.get("JAXTUBE_XLA_THREADS", "0") in ("", "0")):
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "")
                               + " --xla_cpu_multi_thread_eigen=false").strip()


def _measured_jaxlib() -> bool:
    """Whether the installed jaxlib is one the fusion-emitter flag was measured on."""
    try:
        major, minor = (int(part) for part in version("jaxlib").split(".")[:2])
    except (PackageNotFoundError, ValueError):
        return False
    return (0, 7) <= (major, minor) <= (0, 10)


if ("xla_cpu_use_fusion_emitters" not in os.environ.get("XLA_FLAGS", "")
        and os.environ.get("JAXTUBE_XLA_FUSION_EMITTERS", "0") in ("", "0")
        and _measured_jaxlib()):
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "")
                               + " --xla_cpu_use_fusion_emitters=false").strip()


def _cpu_device_count(value: str) -> int:
    """``JAXTUBE_CPU_DEVICES``: a positive integer or ``auto``."""
    if value.strip().lower() == "auto":
        try:
            return len(os.sched_getaffinity(0))
        except AttributeError:  # not on Linux
            return os.cpu_count() or 1
    try:
        count = int(value)
    except ValueError:
        count = 0
    if count < 1:
        raise ValueError(f"JAXTUBE_CPU_DEVICES must be a positive integer or 'auto', got "
                         f"{value!r}.")
    return count


_devices = os.environ.get("JAXTUBE_CPU_DEVICES", "")
if _devices and "xla_force_host_platform_device_count" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " --xla_force_host_platform_"
                               f"device_count={_cpu_device_count(_devices)}").strip()

import jax  # noqa: E402  (after XLA_FLAGS: the flag must be set before JAX starts)

if os.environ.get("JAXTUBE_NO_X64", "0") in ("", "0"):
    jax.config.update("jax_enable_x64", True)
