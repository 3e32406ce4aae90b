"""Every figure script of experiments/ runs in quick mode and writes its PNG.

The three fitting scripts share one persistent compilation cache (same quick-mode data
shapes and model), so only the first compiles the fit.
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SCRIPTS = ("fig4_spline_law", "fig5_7_cantilever_fits", "fig6_pivot_scaling",
           "empirical_2011_representation", "fig9_kite_force_deflection",
           "hidden_effect_workflow")


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("jax-cache")


@pytest.mark.parametrize("script", SCRIPTS)
def test_script_runs_quick_and_writes_its_figure(script, tmp_path, cache):
    figure = tmp_path / f"{script}.png"
    env = dict(os.environ, PYTHONPATH=str(REPO), JAX_COMPILATION_CACHE_DIR=str(cache),
               JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS="0", MPLBACKEND="Agg")
    done = subprocess.run([sys.executable, "-m", f"experiments.{script}",
                           "--quick", "--out", str(figure)], env=env, cwd=REPO,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert figure.stat().st_size > 10_000
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
