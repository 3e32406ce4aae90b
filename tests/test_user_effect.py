"""A user-defined effect (not a built-in) through the Python API and the CLI:
``experiments/effects/tip_mass.py:TipMass``, a point mass at the tip."""

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import fitting as ft
import jaxtube as jt
from fitting._effects import resolve_effect
from fitting._rig import CantileverRig, TubeModel
from jaxtube._cli import main

ROOT = Path(__file__).resolve().parents[1]
EFFECT = f"{ROOT / 'experiments' / 'effects' / 'tip_mass.py'}:TipMass"


def test_user_effect_loads_and_acts_through_the_rig():
    tip_mass = resolve_effect(EFFECT)
    assert tip_mass.name == "tip_mass" and tip_mass.name not in ft.BUILT_IN_EFFECTS
    rig = CantileverRig(segments=8)
    law = jt.LinearLaw(200.0)
    deflection = jnp.asarray([0.01, 0.2])

    @jax.jit
    def force(mass):
        return rig.curve(TubeModel(law, effects=(tip_mass(mass),)), 2e4, 0.075, 1.0,
                         deflection).force

    plain, heavy = force(0.0), force(2.0)
    # Zeroed at the unloaded shape: at small deflection the added weight changes nothing to
    # first order; at large deflection the sagged start shifts the response.
    assert abs(float(heavy[0] - plain[0])) < 0.05 * float(plain[0])
    assert abs(float(heavy[1] - plain[1])) > 1e-3 * float(plain[1])


def test_user_effect_on_the_command_line(tmp_path, capsys):
    data = ROOT / "tests" / "data" / "effects" / "none.csv"
    out = tmp_path / "fit"
    code = main(["fit", str(data), "--effect", EFFECT, "--out", str(out), "--quiet",
                 "--max-iterations", "4"])
    printed = capsys.readouterr().out
    assert code in (0, 1)  # 1: stopped at the iteration cap, outputs written and marked
    assert "tip_mass.mass" in printed
    assert (out / "parameters.json").exists()
    assert np.isfinite(ft.load_law(out / "parameters.json").moment(0.1, 2e4, 0.075))
