"""The shared dataset, the comparison statistics, the demo and bad input (the negative
controls share the effect datasets' compiled model: ``tests/test_diagnose_effects.py``).

- ``tests/data/cantilever_shear.csv`` (a copy of the shared dataset: a tension-field tube
  with Fichter shear, made outside this project): ``shear`` is found and the error falls to
  near the noise.
- ``jaxtube demo`` finds the bundled dataset's hidden effect and writes its outputs.
"""

import json
from pathlib import Path

import numpy as np

import fitting as ft
from fitting._cli import main

DATA = Path(__file__).parent / "data"


def _diagnose(path):
    return ft.diagnose(ft.load_measurements(path), options=ft.DiagnoseOptions(progress=False))


def test_shared_dataset_shear_is_found():
    diagnosis = _diagnose(DATA / "cantilever_shear.csv")
    assert "shear" in diagnosis.verdict
    assert diagnosis.verdict[0] == "shear"
    assert diagnosis.baseline.rmse > 2 * diagnosis.noise
    assert diagnosis.final.rmse <= 1.3 * diagnosis.noise


def test_runs_test_and_chi2_tell_noise_from_misfit():
    """The verdict statistic on residuals we construct: white noise is noise; a smooth
    bias of the same size is systematic."""
    from fitting._diagnose.compare import residual_verdict

    rng = np.random.default_rng(3)

    class Curve:
        def __init__(self, force):
            self.deflection = np.linspace(0.001, 0.1, force.size)
            self.force = force
            self.weight = np.ones(force.size)

    class Fake:  # the attributes residual_verdict reads from a FitResult
        def __init__(self, residuals):
            curves = [Curve(np.zeros(r.size)) for r in residuals]
            self.problem = type("P", (), {"data": curves, "free_index": (0, 1)})()
            self.force = tuple(residuals)
            self.noise = 1.0

    noise = residual_verdict(Fake([rng.standard_normal(20) for _ in range(6)]))
    assert not noise.systematic and 0.5 < noise.chi2 / noise.dof < 1.6
    bias = [np.sin(np.linspace(0, 2 * np.pi, 20)) * 1.5 + 0.3 * rng.standard_normal(20)
            for _ in range(6)]
    misfit = residual_verdict(Fake(bias))
    assert misfit.systematic and misfit.runs_z < -3


def test_demo_finds_the_hidden_effect_and_writes_its_outputs(tmp_path, capsys):
    out = tmp_path / "demo"
    code = main(["demo", "--out", str(out), "--quiet"])
    printed = capsys.readouterr().out
    assert code == 0
    document = json.loads((out / "diagnosis.json").read_text())
    physical = [name for name in document["verdict"] if name in ft.BUILT_IN_EFFECTS]
    assert physical == ["clamp_compliance"]  # what jaxtube/data/README.md says is hidden
    assert document["final"]["rmse_N"] < document["baseline"]["rmse_N"]
    assert document["final"]["rmse_N"] <= 1.3 * document["noise_N"]
    for name in ("fit_0_baseline.png", "fit_1_clamp_compliance.png", "where_it_fails.png",
                 "ranking.png", "before_after.png", "report.txt", "parameters.json"):
        assert (out / name).stat().st_size > 0, name
    assert "verdict: " in printed and "hidden in the demo data: clamp_compliance" in printed
    assert np.isfinite(ft.load_law(out / "parameters.json").moment(0.05, 2e4, 0.075))


def test_diagnose_bad_input_writes_nothing(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("curve,setup,pressure_bar,radius_m,length_m,deflection_mm,force_N\n"
                   "a,cantilever_tip,0.2,0.075,1.0,1.0,abc\n")
    out = tmp_path / "out"
    assert main(["diagnose", str(bad), "--out", str(out), "--quiet"]) == 2
    assert "bad.csv" in capsys.readouterr().err
    assert not out.exists()
    assert main(["diagnose", str(DATA / "effects" / "none.csv"), "--out", str(out),
                 "--candidates", "shear,warp_drive"]) == 2
    assert "warp_drive" in capsys.readouterr().err and not out.exists()
