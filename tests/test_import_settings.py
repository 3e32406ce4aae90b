"""What ``import jaxtube`` switches on (README, "Float64" and "Threads"), checked in fresh
interpreters: float64, single-threaded XLA CPU kernels, XLA's CPU fusion emitters off (compile
time), the opt-outs, and the CPU devices ``JAXTUBE_CPU_DEVICES`` asks for."""

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
             if k not in ("XLA_FLAGS", "JAXTUBE_XLA_THREADS", "JAXTUBE_NO_X64",
                          "JAXTUBE_CPU_DEVICES", "JAXTUBE_XLA_FUSION_EMITTERS")}
    clean.update(env, PYTHONPATH=str(REPO), JAX_PLATFORMS="cpu")
    done = subprocess.run([sys.executable, "-c", PROBE], env=clean, capture_output=True,
                          text=True, timeout=120, check=True)
    flags, x64 = done.stdout.rstrip("\n").split("\n")[-2:]
    return flags, x64 == "True"


EIGEN, EMITTERS = "--xla_cpu_multi_thread_eigen=false", "--xla_cpu_use_fusion_emitters=false"


@pytest.mark.parametrize("env, flags, x64", [
    ({}, f"{EIGEN} {EMITTERS}", True),
    ({"JAXTUBE_XLA_THREADS": "1", "JAXTUBE_XLA_FUSION_EMITTERS": "1"}, "", True),
    ({"XLA_FLAGS": "--xla_cpu_multi_thread_eigen=true --xla_cpu_use_fusion_emitters=true"},
     "--xla_cpu_multi_thread_eigen=true --xla_cpu_use_fusion_emitters=true", True),
    ({"XLA_FLAGS": "--xla_force_host_platform_device_count=2"},
     f"--xla_force_host_platform_device_count=2 {EIGEN} {EMITTERS}", True),
    ({"JAXTUBE_NO_X64": "1"}, f"{EIGEN} {EMITTERS}", False),
    ({"JAXTUBE_CPU_DEVICES": "3"},
     f"{EIGEN} {EMITTERS} --xla_force_host_platform_device_count=3", True),
    ({"JAXTUBE_CPU_DEVICES": "3", "XLA_FLAGS": "--xla_force_host_platform_device_count=2"},
     f"--xla_force_host_platform_device_count=2 {EIGEN} {EMITTERS}", True),
])
def test_import_sets_float64_and_single_threaded_kernels_unless_told_not_to(env, flags, x64):
    assert _run(**env) == (flags, x64)


def test_cpu_devices_take_effect_and_a_bad_count_is_named():
    clean = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    clean.update(PYTHONPATH=str(REPO), JAX_PLATFORMS="cpu", JAXTUBE_CPU_DEVICES="2")
    done = subprocess.run([sys.executable, "-c", "import jaxtube, jax; print(jax.device_count())"],
                          env=clean, capture_output=True, text=True, timeout=120, check=True)
    assert done.stdout.strip().split("\n")[-1] == "2"
    clean["JAXTUBE_CPU_DEVICES"] = "zero"
    done = subprocess.run([sys.executable, "-c", "import jaxtube"], env=clean,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode != 0
    assert "JAXTUBE_CPU_DEVICES must be a positive integer or 'auto', got 'zero'" in done.stderr
