"""``experiments/workflow.ipynb`` (load, fit, compare, diagnose, a custom effect, refit,
sweep) executes without error, is stored without outputs, and reaches the numbers it
promises: the new effect brings the error to the noise and finds the hidden mass."""

import json
import os
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

REPO = Path(__file__).resolve().parents[1]
NOTEBOOK = REPO / "experiments" / "workflow.ipynb"


def test_notebook_is_stored_without_outputs():
    notebook = json.loads(NOTEBOOK.read_text())
    for cell in notebook["cells"]:
        if cell["cell_type"] == "code":
            assert cell["outputs"] == [] and cell["execution_count"] is None


@pytest.mark.slow
def test_workflow_notebook_executes(tmp_path):
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    # The kernel inherits this process's environment (the single-threaded XLA kernels of
    # tests/conftest.py) plus its persistent compilation cache, and runs without progress bars.
    import jax

    kernel_env = {"JAXTUBE_NOTEBOOK_QUIET": "1",
                  "JAX_COMPILATION_CACHE_DIR": jax.config.jax_compilation_cache_dir,
                  "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": "1"}
    saved = {key: os.environ.get(key) for key in kernel_env}
    os.environ.update(kernel_env)
    try:
        NotebookClient(notebook, timeout=600, kernel_name="python3",
                       resources={"metadata": {"path": str(NOTEBOOK.parent)}}).execute()
    finally:
        for key, value in saved.items():
            if value is None:
                del os.environ[key]
            else:
                os.environ[key] = value
    text = "\n".join(output.get("text", "") for cell in notebook.cells
                     if cell.cell_type == "code" for output in cell.outputs)
    errors = [o for cell in notebook.cells if cell.cell_type == "code" for o in cell.outputs
              if o.output_type == "error"]
    assert not errors, errors
    assert "fitted tip mass" in text and "failed: 0" in text, text[-3000:]
    # The refit's closing numbers: the mass within 10 % of the hidden 0.5 kg, and the
    # residuals called noise.
    line = next(s for s in text.splitlines() if s.startswith("fitted tip mass"))
    mass = float(line.split()[3])
    assert 0.45 < mass < 0.55, line
    verdict = text.split("residuals now:")[1].splitlines()[0].strip()
    assert verdict.startswith("Noise:"), verdict
    figures = sum("image/png" in o.get("data", {}) for cell in notebook.cells
                  if cell.cell_type == "code" for o in cell.outputs)
    assert figures >= 5
