"""Calibration (issue 3): parameter recovery, held-out prediction, loss gradient through the
implicit solve, the CLI and its bad-input behaviour.

Data: ``tests/data/calibration_spline.csv``, made by ``experiments/make_calibration_data.py``
with the continuum shooting solver of ``fitting.continuum`` (an independent formulation and
solver) from a known paper-form spline law; see ``tests/data/README.md``.
"""

import dataclasses
import json
from pathlib import Path

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import fitting as ft
import jaxtube as jt
from experiments import make_calibration_data
from fitting._bench import effects as fx
from fitting._calibrate import problem as _calibrate
from fitting._calibrate.parameters_file import without_effects_words
from fitting._cli import main
from jaxtube import _stored_programs as jt_stored

DATA = Path(__file__).parent / "data" / "calibration_spline.csv"
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def data():
    return ft.load_measurements(DATA)


@pytest.fixture(scope="module")
def result(data):
    return ft.fit(data, options=ft.FitOptions(progress=False))


def test_recovers_known_scaling_factors_within_uncertainty(data, result):
    """Every identified A and B of the true law lies within 3 reported standard errors; the
    unwrinkled-regime pivot (which every curve passes) is identified, and the pivots the
    data do not resolve (the curves stop at 85 % of the collapse load) are flagged."""
    assert result.convergence.converged, result.convergence.message
    truth = ft.PivotScaling().physical(
        ft.PivotScaling().vector(make_calibration_data.true_law(), *result.problem.reference),
        *result.problem.reference)
    identified = 0
    for estimate in result.parameters:
        if not estimate.identified:
            continue
        identified += 1
        z = abs(estimate.value - truth[estimate.name]) / estimate.standard_error
        assert z < 3.0, (estimate, truth[estimate.name])
    for name in ("kappa[1].A", "kappa[1].B", "M[1].A", "M[1].B"):
        assert result.parameter(name).identified, (name, result.identifiability)
    assert identified >= 4
    assert not result.parameter("kappa[3].B").identified  # the collapsed regime: no data
    assert any("pivot(s)" in sentence for sentence in result.identifiability)
    # The fit reaches the noise: residual variance per noise variance near 1.
    assert result.rmse < 1.3 * result.noise
    assert 0.5 < result.residual_variance < 1.6


def test_band_is_finite_and_narrower_than_the_noise_where_data_are(data, result):
    batch = result.problem.batch
    force, sd = result.predict(batch.pressure, batch.radius, batch.length, batch.deflection)
    assert np.all(np.isfinite(sd[batch.mask])) and np.all(sd[batch.mask] > 0)
    assert np.median(sd[batch.mask]) < result.noise  # the band is narrower than the noise


def test_held_out_pressure_is_predicted_within_twice_the_noise(data):
    """Fit the 0.15 and 0.35 bar curves; predict the 0.25 bar curves. The held-out curves
    stay in the batch with a negligible weight (1e-12), so the fit reuses the compiled model
    of the full data set and predicts them in the same solve."""
    held_out = {c.name for c in data if abs(c.pressure - 0.25e5) < 1.0}
    assert len(held_out) == 2
    curves = tuple(dataclasses.replace(c, weight=np.full(c.point_count, 1e-12))
                   if c.name in held_out else c for c in data)
    fitted = ft.fit(ft.MeasuredData(curves, source="training"),
                    options=ft.FitOptions(progress=False, noise_N=ft.estimate_noise(data)))
    errors = [force - curve.force for curve, force in zip(data, fitted.force)
              if curve.name in held_out]
    training = [force - curve.force for curve, force in zip(data, fitted.force)
                if curve.name not in held_out]
    rmse = float(np.sqrt(np.mean(np.concatenate(errors) ** 2)))
    assert rmse < 2.0 * fitted.noise, (rmse, fitted.noise)
    assert float(np.sqrt(np.mean(np.concatenate(training) ** 2))) < 1.3 * fitted.noise


def test_loss_gradient_through_implicit_solve_matches_finite_differences(result):
    """d(loss)/d(theta) = J^T r from forward-mode derivatives through the equilibrium
    (implicit function theorem) equals central finite differences of the loss. Every
    coordinate is freed, the ones the fit held as undetermined (M[2].A) included."""
    problem = result.problem.with_free(list(result.problem.names), result.vector)
    assert "M[2].A" in result.convergence.held  # held by the fit, derived here all the same
    x = np.asarray(result.vector)[np.asarray(problem.free_index)] + 0.05  # a non-zero gradient
    args = problem.residual_args()

    def loss(values):
        r, _, _ = _calibrate._residuals_and_jacobian(jnp.asarray(problem.full(values)), *args,
                                                     **problem.static())
        return 0.5 * float(np.sum(np.asarray(r) ** 2))

    r, jac, _ = _calibrate._residuals_and_jacobian(jnp.asarray(problem.full(x)), *args,
                                                   **problem.static())
    jac = np.asarray(jac)[:, np.asarray(problem.free_index)]
    gradient = jac.T @ np.asarray(r)
    names = problem.free_names
    for name in ("kappa[1].A", "M[1].B", "M[2].A"):
        i = names.index(name)
        step = 1e-5
        plus, minus = x.copy(), x.copy()
        plus[i] += step
        minus[i] -= step
        numeric = (loss(plus) - loss(minus)) / (2 * step)
        assert numeric == pytest.approx(gradient[i], rel=2e-5, abs=1e-6 * abs(gradient).max())


def test_unidentifiable_exponent_is_flagged_in_words(data):
    """A curve at one radius and one pressure cannot determine B: the fit says so in
    words, naming the spread of p r^3 in the data."""
    single = ft.MeasuredData(tuple(c for c in data if c.name == "p0.25-r90"), source="single")
    fitted = ft.fit(single, options=ft.FitOptions(progress=False, max_iterations=15))
    for name in ("kappa[1].B", "M[1].B"):
        assert not fitted.parameter(name).identified
    sentence = next(s for s in fitted.identifiability if "determine B" in s)
    assert "pressures or radii" in sentence
    assert "M[1].B" in sentence and "ratio of 1.00" in sentence


def test_fit_cli_writes_parameters_that_simulate_and_predict_load(data, tmp_path, capsys):
    out = tmp_path / "fit"
    code = main(["fit", str(DATA), "--out", str(out), "--quiet"])
    printed = capsys.readouterr().out
    assert code == 0
    assert {"parameters.json", "fit.png", "curves.csv"} <= {p.name for p in out.iterdir()}
    assert "kappa[1].A" in printed and "overall" in printed and "RMSE" in printed
    document = json.loads((out / "parameters.json").read_text())
    law = ft.load_law(out / "parameters.json")
    assert document["rmse_N"] < 1.3 * document["noise_N"]
    np.testing.assert_allclose(np.asarray(law.moment_exponent),
                               document["law"]["moment_exponent"])

    predicted = tmp_path / "predict"
    code = main(["predict", "--params", str(out / "parameters.json"), "--pressure-bar", "0.3",
                 "--radius-m", "0.075", "--length-m", "1.0", "--max-deflection-mm", "30",
                 "--points", "12", "--out", str(predicted)])
    assert code == 0
    rows = (predicted / "prediction.csv").read_text().splitlines()
    assert rows[0] == "deflection_mm,force_N,force_low_N,force_high_N" and len(rows) == 13
    _, force, low, high = (float(v) for v in rows[-1].split(","))
    assert 0 < low < force < high

    simulated = tmp_path / "simulate"
    example = ROOT / "jaxtube" / "examples" / "cantilever.toml"
    code = main(["simulate", str(example), "--params", str(out / "parameters.json"),
                 "--steps", "4", "--out", str(simulated), "--quiet"])
    assert code == 0
    summary = json.loads((simulated / "summary.json").read_text())
    assert summary["converged_steps"] == 4


@pytest.mark.parametrize("case", ["missing column", "out is a file", "unknown parameter",
                                  "bad prior"])
def test_fit_cli_bad_input_is_a_clear_error_and_writes_nothing(tmp_path, capsys, case):
    out = tmp_path / "out"
    data = DATA
    extra = []
    if case == "missing column":
        data = tmp_path / "bad.csv"
        lines = DATA.read_text().splitlines()
        data.write_text("\n".join(",".join(line.split(",")[:-1]) for line in lines) + "\n")
    elif case == "out is a file":
        out.write_text("not a directory")
    elif case == "unknown parameter":
        extra = ["--fix", "kappa[9].B=1.0"]
    else:
        extra = ["--prior", "M[1].B=1.0"]
    with pytest.raises(SystemExit) if case == "bad prior" else _no_raise():
        code = main(["fit", str(data), "--out", str(out), "--quiet", *extra])
        assert code == 2
    err = capsys.readouterr().err
    assert "error" in err
    if case == "missing column":
        assert "bad.csv" in err and "force" in err
    if case == "unknown parameter":
        assert "kappa[9].B" in err
    if case == "out is a file":
        assert out.read_text() == "not a directory"
    else:
        assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".partial")]


class _no_raise:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


class _TubeLaws(eqx.Module):
    """What an effect's ``apply`` reads and writes of a structure's parameters."""

    bending_laws: tuple


def test_load_law_folds_the_model_structure_extensions_in(tmp_path):
    """A parameters file from a fit with ``radius_scaling`` and ``unwrinkled_linearity``:
    the law read back is, at every radius, the law the fit's model used there (the effects'
    own ``apply``), so ``simulate`` and ``sweep`` use the fitted law, not its base."""
    base = jt.SplineLaw.from_pivots([0.02, 0.3, 1.5], [12.0, 20.0, 24.0], 2.4e4, 0.07,
                                    curvature_exponent=[1.0, 0.9, 1.1],
                                    moment_exponent=[1.0, 1.05, 0.95],
                                    pivots_per_regime=(1, 1, 1))
    reference = {"pressure_Pa": 2.4e4, "radius_m": 0.07}
    effects = {"radius_scaling": {"curvature_radius_excess": -3.0,
                                  "moment_radius_excess": 0.1},
               "unwrinkled_linearity": {"linear_share": 0.4}}
    document = {"format": "jaxtube-fit", "version": 1, "reference": reference,
                "effects": effects,
                "law": {"type": "SplineLaw", "form": "paper", "pivots_per_regime": [1, 1, 1],
                        "residual_stiffness_ratio": 0.01,
                        **{name: np.asarray(getattr(base, name)).tolist() for name in (
                            "curvature_scale", "curvature_exponent", "moment_scale",
                            "moment_exponent")},
                        "curvature_radius_exponent": None, "moment_radius_exponent": None}}
    path = tmp_path / "parameters.json"
    path.write_text(json.dumps(document))
    loaded = ft.load_law(path)
    curvature = jnp.linspace(0.0, 3.0, 61)
    for pressure, radius in ((2.4e4, 0.07), (1.5e4, 0.05), (3.0e4, 0.1)):
        specimen = fx.RigSpecimen(pressure=pressure, radius=radius, length=1.0, tube=0,
                                  clamp=None, clamp_length=0.0, reference_pressure=2.4e4,
                                  reference_radius=0.07)
        params = _TubeLaws((base,))
        for effect in (ft.RadiusScaling(-3.0, 0.1), ft.UnwrinkledLinearity(0.4)):
            params = effect.apply(params, specimen)
        expected = params.bending_laws[0].moment(curvature, pressure, radius)
        np.testing.assert_allclose(loaded.moment(curvature, pressure, radius), expected,
                                   rtol=1e-12, atol=1e-12)
    assert float(loaded.linear_share) == 0.4
    assert without_effects_words(path) == ""  # both are folded into the law
    document["effects"]["shear"] = {"flexibility": 6e-5}
    path.write_text(json.dumps(document))
    assert "shear not applied" in without_effects_words(path)


def test_the_fit_program_loaded_from_the_store_gives_the_same_residuals_and_jacobian(
        result, tmp_path, monkeypatch):
    """The command line stores the fit's residual-and-Jacobian program
    (``jaxtube.stored_jit``): exported, then loaded by a new wrapper as a later process would,
    it gives ``jax.jit``'s residuals, Jacobian and predictions exactly."""
    problem = result.problem
    arguments = (jnp.asarray(problem.full(problem.base[np.asarray(problem.free_index)])),
                 *problem.residual_args())
    want = _calibrate._residuals_and_jacobian.jitted(*arguments, **problem.static())
    monkeypatch.delenv("JAXTUBE_NO_COMPILATION_CACHE", raising=False)
    jt.enable_traced_program_store(tmp_path)
    try:
        exported = _calibrate._residuals_and_jacobian(*arguments, **problem.static())

        def no_export(*_):
            raise AssertionError("the stored program was traced again, not loaded")

        monkeypatch.setattr(jt_stored, "_export", no_export)
        loaded = jt.stored_jit(_calibrate._residuals_and_jacobian.__wrapped__,
                               static_argnames=("rig", "scaling", "effects"))(
            *arguments, **problem.static())
    finally:
        jt.disable_traced_program_store()
    assert len(list(tmp_path.iterdir())) == 1
    for got in (exported, loaded):
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])
        assert type(got[2]) is type(want[2])
        for field in ("force", "converged", "iterations", "joint_regime"):
            np.testing.assert_array_equal(getattr(got[2], field), getattr(want[2], field))
