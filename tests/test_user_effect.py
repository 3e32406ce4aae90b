"""A user-defined effect (not a built-in) end to end, through the Python API and the CLI:
``experiments/effects/tip_mass.py:TipMass``, a point mass hanging at the tip.

- The effect, written by a user in its own file, acts through the rig exactly as the
  independent continuum solver's tip mass does.
- ``tests/data/effects/tip_mass.csv`` hides a 0.5 kg tip mass (continuum solver, several
  pressures, radii and lengths, noise). Passed as an extra candidate, the user's effect is
  ranked with the built-ins, found, and brings the error to the noise; the built-in
  physical effects are not claimed instead.
"""

import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import fitting as ft
import jaxtube as jt
from fitting import continuum
from fitting._bench.effects import resolve_effect
from fitting._bench.rig import CantileverRig, TubeModel
from fitting._cli import main

ROOT = Path(__file__).resolve().parents[1]
EFFECT = f"{ROOT / 'experiments' / 'effects' / 'tip_mass.py'}:TipMass"
HIDDEN = ROOT / "tests" / "data" / "effects" / "tip_mass.csv"
HIDDEN_MASS = 0.5  # kg (tests/data/effects/README.md)


def test_user_effect_matches_the_continuum_tip_mass():
    """Linear law EI = 200 N m^2, L = 1 m, a 5 kg tip mass: the rig's force at the
    continuum solver's deflections (zeroed at the sagged shape) is the continuum's load. A
    linear law makes the mass act only through large rotations: loads up to P L^2 / EI = 1."""
    tip_mass = resolve_effect(EFFECT)
    assert tip_mass.name == "tip_mass" and tip_mass.name not in ft.BUILT_IN_EFFECTS
    loads = np.array([5.0, 200.0])
    reference = continuum.CantileverModel(1.0, continuum.linear_law(200.0), tip_mass=5.0)
    deflection = np.array([reference.tip_deflection(p) for p in loads])
    plain = continuum.CantileverModel(1.0, continuum.linear_law(200.0))
    # The mass matters at large deflection (the test is not trivially passed without it).
    assert abs(deflection[1] - plain.tip_deflection(loads[1])) > 0.02 * deflection[1]
    rig = CantileverRig(segments=20)

    @jax.jit
    def force(mass):
        model = TubeModel(jt.LinearLaw(200.0), effects=(tip_mass(mass),))
        prediction = rig.curve(model, 2e4, 0.075, 1.0, jnp.asarray(deflection))
        return prediction.force, prediction.converged

    predicted, converged = force(5.0)
    assert bool(np.all(converged))
    np.testing.assert_allclose(np.asarray(predicted), loads, rtol=3e-3)


@pytest.fixture(scope="module")
def hidden_tip_mass():
    data = ft.load_measurements(HIDDEN)
    return ft.diagnose(data, user_effects=(resolve_effect(EFFECT),),
                       options=ft.DiagnoseOptions(progress=False))


def test_hidden_user_effect_is_found_through_the_api(hidden_tip_mass):
    diagnosis = hidden_tip_mass
    assert "tip_mass" in diagnosis.candidates
    assert diagnosis.verdict[0] == "tip_mass", diagnosis.statements
    assert not [name for name in diagnosis.verdict if name in ft.BUILT_IN_EFFECTS]
    estimate = diagnosis.steps[0].candidates[0].estimates["tip_mass.mass"]
    assert estimate == pytest.approx(HIDDEN_MASS, rel=0.15)
    assert diagnosis.baseline.rmse > 1.3 * diagnosis.noise  # the baseline fails the criterion
    assert diagnosis.final.rmse <= 1.3 * diagnosis.noise


def test_hidden_user_effect_on_the_command_line(tmp_path, capsys):
    out = tmp_path / "diagnosis"
    code = main(["diagnose", str(HIDDEN), "--effect", EFFECT, "--out", str(out), "--quiet",
                 "--max-additions", "1"])
    printed = capsys.readouterr().out
    assert code == 0
    document = json.loads((out / "diagnosis.json").read_text())
    assert document["verdict"] == ["tip_mass"]
    assert "tip_mass" in document["candidates_considered"]
    assert document["final"]["rmse_N"] < document["baseline"]["rmse_N"]
    assert "tip_mass" in printed and (out / "fit_1_tip_mass.png").exists()


def test_user_effect_in_a_fit_on_the_command_line(tmp_path, capsys):
    out = tmp_path / "fit"
    code = main(["fit", str(HIDDEN), "--effect", EFFECT, "--out", str(out), "--quiet",
                 "--max-iterations", "4"])
    printed = capsys.readouterr().out
    assert code in (0, 1)  # 1: stopped at the iteration cap, outputs written and marked
    assert "tip_mass.mass" in printed
    assert (out / "parameters.json").exists()
    assert np.isfinite(ft.load_law(out / "parameters.json").moment(0.1, 2e4, 0.075))
