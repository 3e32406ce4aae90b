"""Every figure script of experiments/ runs in quick mode (``python -m experiments.NAME``)
and writes its PNG.

The scripts use the suite's persistent compilation cache (``tests/conftest.py``): the three
fitting scripts share the fit's programs (same quick-mode data shapes and model), and a
later run of the suite finds them all compiled.
"""

import os
import subprocess
import sys
from pathlib import Path

import jax
import pytest

REPO = Path(__file__).resolve().parents[1]
SCRIPTS = ("fig4_spline_law", "fig5_7_cantilever_fits", "fig6_pivot_scaling",
           "empirical_2011_representation", "fig9_kite_force_deflection",
           "hidden_effect_workflow")


@pytest.mark.parametrize("script", SCRIPTS)
def test_script_runs_quick_and_writes_its_figure(script, tmp_path):
    figure = tmp_path / f"{script}.png"
    env = dict(os.environ, PYTHONPATH=str(REPO), MPLBACKEND="Agg",
               JAX_COMPILATION_CACHE_DIR=jax.config.jax_compilation_cache_dir,
               JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS=str(
                   jax.config.jax_persistent_cache_min_compile_time_secs))
    done = subprocess.run([sys.executable, "-m", f"experiments.{script}",
                           "--quick", "--out", str(figure)], env=env, cwd=REPO,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert figure.stat().st_size > 10_000
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
