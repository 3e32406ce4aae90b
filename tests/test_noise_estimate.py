"""The model-free noise estimate against each bundled dataset's generating noise floor.

The floor is the RMSE of the noise-free truth, evaluated at the recorded (noisy)
deflections, against the recorded forces: what a perfect model reaches, force noise and
deflection noise seen through the slope together. It is computed by the scripts that made
the data, from the independent continuum solver (``experiments/make_hidden_effect_designs.py``
writes ``tests/data/effects/designs.json``; ``experiments/noise_floors.py`` writes
``tests/data/noise_floors.json`` for the datasets made before). No JAX compilation here.

:func:`fitting.estimate_noise_with_error` is the higher-order estimator of issue 16; the
diagnosis and the fit use it (:func:`fitting.estimate_noise` is its value).
"""

import json
from pathlib import Path

import numpy as np
import pytest

import fitting as ft
from fitting._calibrate.noise import DEFAULT_ORDER
from fitting._diagnose import diagnosis

DATA = Path(__file__).parent / "data"
FLOORS = {**json.loads((DATA / "noise_floors.json").read_text()),
          **{entry["file"]: entry["noise_floor_N"] for entry in
             json.loads((DATA / "effects" / "designs.json").read_text()).values()}}


@pytest.mark.parametrize("path", sorted(FLOORS))
def test_noise_estimate_within_a_quarter_of_the_generating_floor(path):
    data = ft.load_measurements(DATA.parent.parent / path)
    estimate = ft.estimate_noise_with_error(data)
    assert abs(estimate.noise_N / FLOORS[path] - 1) <= 0.25, (estimate, FLOORS[path])
    assert 0 < estimate.standard_error_N < 0.25 * estimate.noise_N
    assert ft.estimate_noise(data) == estimate.noise_N  # what the fit and diagnosis use


def test_noise_estimate_is_unbiased_on_a_bending_curve_and_its_error_is_right():
    """White noise on a strongly bending, unequally sampled curve (a saturating force law
    like a wrinkling tube's): the quadratic-annihilating differences are unbiased, the
    three-point (linear) ones are not, and the reported standard error matches the scatter
    over repeated draws."""
    rng = np.random.default_rng(0)
    sigma = 0.1

    class Curve:
        def __init__(self, x, y):
            self.deflection, self.force = x, y

    estimates, errors, linear = [], [], []
    for _ in range(300):
        curves = []
        for scale in (5.0, 10.0, 20.0):
            x = np.sort(rng.uniform(0.0, 0.1, 14))
            curves.append(Curve(x, scale * np.tanh(40 * x) + sigma * rng.standard_normal(14)))
        estimate = ft.estimate_noise_with_error(curves)
        estimates.append(estimate.noise_N)
        errors.append(estimate.standard_error_N)
        linear.append(ft.estimate_noise_with_error(curves, order=1).noise_N)
    assert np.mean(estimates) == pytest.approx(sigma, rel=0.05)
    assert np.mean(linear) > 1.3 * sigma  # the locally linear assumption fails here
    assert np.std(estimates) == pytest.approx(np.mean(errors), rel=0.25)


class _Stop(Exception):
    """Raised by the stand-in estimate: the diagnosis stops before its first fit."""


@pytest.mark.parametrize("order", [None, 3])
def test_the_diagnosis_estimates_the_noise_at_the_order_asked(monkeypatch, order):
    """``DiagnoseOptions.noise_order`` (default :data:`DEFAULT_ORDER`) is the order the
    diagnosis' noise estimate is made at."""
    asked = []

    def estimate(data, noise_order):
        asked.append(noise_order)
        raise _Stop

    monkeypatch.setattr(diagnosis, "estimate_noise_with_error", estimate)
    path = sorted(FLOORS)[0]
    options = ft.DiagnoseOptions(progress=False) if order is None else \
        ft.DiagnoseOptions(progress=False, noise_order=order)
    with pytest.raises(_Stop):
        ft.diagnose(ft.load_measurements(DATA.parent.parent / path), options=options)
    assert asked == [DEFAULT_ORDER if order is None else order]
