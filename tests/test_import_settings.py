"""What ``import jaxtube`` switches on (README, "Float64" and "Threads"), checked in fresh
interpreters: float64, single-threaded XLA CPU kernels, and both opt-outs."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PROBE = ("import os, jaxtube, jax; print(os.environ.get('XLA_FLAGS', '')); "
         "print(jax.config.jax_enable_x64)")


def _run(**env):
    clean = {k: v for k, v in os.environ.items()
             if k not in ("XLA_FLAGS", "JAXTUBE_XLA_THREADS", "JAXTUBE_NO_X64")}
    clean.update(env, PYTHONPATH=str(REPO), JAX_PLATFORMS="cpu")
    done = subprocess.run([sys.executable, "-c", PROBE], env=clean, capture_output=True,
                          text=True, timeout=120, check=True)
    flags, x64 = done.stdout.rstrip("\n").split("\n")[-2:]
    return flags, x64 == "True"


@pytest.mark.parametrize("env, flags, x64", [
    ({}, "--xla_cpu_multi_thread_eigen=false", True),
    ({"JAXTUBE_XLA_THREADS": "1"}, "", True),
    ({"XLA_FLAGS": "--xla_cpu_multi_thread_eigen=true"}, "--xla_cpu_multi_thread_eigen=true",
     True),
    ({"XLA_FLAGS": "--xla_force_host_platform_device_count=2"},
     "--xla_force_host_platform_device_count=2 --xla_cpu_multi_thread_eigen=false", True),
    ({"JAXTUBE_NO_X64": "1"}, "--xla_cpu_multi_thread_eigen=false", False),
])
def test_import_sets_float64_and_single_threaded_kernels_unless_told_not_to(env, flags, x64):
    assert _run(**env) == (flags, x64)
