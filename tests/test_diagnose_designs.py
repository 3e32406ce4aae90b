"""The diagnosis on designs unlike the older tests (issue 16): a tension-field truth over
several radii and pressures with one effect hidden, and controls with nothing hidden.

Data: ``tests/data/effects/tf_*.csv``, made by the independent continuum solver
(``experiments/make_hidden_effect_designs.py``; not jaxtube's chain), with each dataset's
generating noise floor (the noise-free truth at the recorded deflections against the recorded
forces) in ``tests/data/effects/designs.json``. The paper scaling cannot follow a
tension-field truth across radii, and the one-pivot spline cannot follow its linear
unwrinkled regime, so the model-structure extensions ``radius_scaling`` and
``unwrinkled_linearity`` may join the verdict; no physical effect but the hidden one may.

This file runs two designs (README "Hidden-effect designs"): ``tf_reinforcement``, the
issue's failing design (reinforcement's score is 0 at step 1, where the likelihood ratio on
its refit later adds it), and the one-radius control; their 6 x 14 shape shares the compiled
model of ``tests/test_diagnose_effects.py``. The other four (``tf_clamp_compliance``,
``tf_self_weight``, the four-curve control and ``tf_shear``, the only design that exercises
the pivot refinement end to end, with a second compiled model) are study-sized runs of
several minutes each: they run, with the checks their tests made, in
``experiments/diagnose_designs.py`` (``python -m experiments.diagnose_designs``, exit
status 1 on a failure; ``experiments/results/diagnose_designs.txt``). The other rules
(blocked cross-validation and its validity check, plausible sizes, the boundary mixture, the
second start of a refit, the refinement's start) are tested on constructed inputs in
``tests/test_diagnosis_rules.py``.
"""

import functools
import json
from pathlib import Path

import pytest

import fitting as ft

EFFECTS = Path(__file__).parent / "data" / "effects"
DESIGNS = json.loads((EFFECTS / "designs.json").read_text())
FLOORS = json.loads((EFFECTS.parent / "noise_floors.json").read_text())


@functools.cache
def diagnosis_of(name: str) -> ft.Diagnosis:
    data = ft.load_measurements(EFFECTS / f"{name}.csv")
    return ft.diagnose(data, options=ft.DiagnoseOptions(progress=False))


def floor(name: str) -> float:
    return DESIGNS[name]["noise_floor_N"]


def physical_effects(diagnosis: ft.Diagnosis) -> list[str]:
    """The verdict's physical effects (the built-in ones; not the model's extensions)."""
    return [effect for effect in diagnosis.verdict if effect in ft.BUILT_IN_EFFECTS]


def test_reinforcement_is_found_by_the_likelihood_ratio_on_its_refit():
    """Six curves, 2 pressures x 3 radii, EI_r = 20 N m^2 hidden. The verdict is
    reinforcement (with the model-structure extensions); its refit decided, whatever its
    score said."""
    name = "tf_reinforcement"
    diagnosis = diagnosis_of(name)
    physical = physical_effects(diagnosis)
    assert physical == ["reinforcement"], diagnosis.report()
    assert set(diagnosis.verdict) <= {"reinforcement", *ft.MODEL_EXTENSIONS}
    assert diagnosis.baseline.rmse > 1.3 * floor(name)  # the baseline really misses
    assert diagnosis.final.rmse <= 1.3 * floor(name), diagnosis.report()
    for step in diagnosis.steps:
        chosen = step.candidates[0]
        assert chosen.significant and chosen.lr_p_value < 0.01 / len(step.candidates)
        assert chosen.decided_by.startswith("added if best: likelihood ratio")
    rejected = [row for step in diagnosis.steps for row in step.candidates[1:]
                if not row.significant] + list(diagnosis.final_candidates)
    assert rejected and all(row.decided_by.startswith("not added: ") for row in rejected)
    words = " ".join(diagnosis.statements)
    assert "likelihood-ratio test on the refit" in words and "orders the refits only" in words
    assert "Noise " in words and "residual scatter" in words


def test_control_with_one_radius_names_no_physical_effect():
    """Six curves at one radius, tension-field truth, nothing hidden. The paper's spline
    misses (its one-pivot unwrinkled regime bends where the tube stays linear): the verdict
    is the model-structure extension ``unwrinkled_linearity`` alone, no physical effect, and
    the final RMSE is within 1.3x the generating floor (before that candidate existed, this
    control ended at 1.44x, and under an earlier rule with a false ``reinforcement``)."""
    name = "tf_none_one_radius"
    diagnosis = diagnosis_of(name)
    assert not physical_effects(diagnosis), diagnosis.report()
    assert "unwrinkled_linearity" in diagnosis.verdict
    assert diagnosis.baseline.rmse > 1.3 * floor(name)
    assert diagnosis.final.rmse <= 1.3 * floor(name), diagnosis.report()
    assert abs(diagnosis.noise / floor(name) - 1.0) <= 0.25


def test_noise_estimate_and_its_error_are_reported():
    diagnosis = diagnosis_of("tf_reinforcement")
    estimate = diagnosis.noise_estimate
    assert estimate is not None and estimate.noise_N == diagnosis.noise
    assert 0 < estimate.standard_error_N < 0.3 * estimate.noise_N
    document = diagnosis.to_json()
    assert document["noise_standard_error_N"] == pytest.approx(estimate.standard_error_N)


def test_the_fit_with_the_hidden_effect_converges_by_itself():
    """``fit`` with the effect the data hide (Fichter shear, continuum solver) converges on
    its own to the generating floor: the effect starts at its typical size, undetermined
    coordinates are held and named, stagnation ends the iterations. All candidates are
    compiled in (the others fixed at their null), so the diagnosis' compiled model serves."""
    path = "tests/data/effects/shear.csv"
    data = ft.load_measurements(Path(__file__).parents[1] / path)
    candidates = ft.default_candidates(ft.PivotScaling())
    fixed = {f"{c.name}.{p.name}": p.null for c in candidates if c is not ft.Shear
             for p in c.parameters}
    result = ft.fit(data, effects=candidates, options=ft.FitOptions(fixed=fixed,
                                                                     progress=False))
    assert result.convergence.converged, result.convergence.message
    assert result.rmse <= 1.3 * FLOORS[path]
    if result.convergence.held:
        assert result.identifiability[0].startswith("Held at the physics-based first guess")
        assert all(n in result.identifiability[0] for n in result.convergence.held)
        assert "HELD" in result.table()
