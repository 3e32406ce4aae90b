"""The diagnosis' decision pieces on constructed inputs (no model, no compilation): the
blocked cross-validation against brute-force refits, its validity check, and plausible
sizes."""

import types

import numpy as np
import pytest

import fitting as ft
from fitting._diagnose.selection import implausible_words
from fitting._diagnose.validation import fold_of_points


def _linear_fit(design: np.ndarray, force: np.ndarray, deflection: np.ndarray, noise=0.5):
    """A stand-in for a FitResult of the linear model ``force = design @ theta`` (curves x
    points layout of ``force``), at its least-squares optimum."""
    flat = force.reshape(-1)
    theta = np.linalg.lstsq(design, flat, rcond=None)[0]
    residual = (design @ theta - flat) / noise
    problem = types.SimpleNamespace(
        free_index=tuple(range(design.shape[1])),
        free_bounds=(np.full(design.shape[1], -np.inf), np.full(design.shape[1], np.inf)),
        batch=types.SimpleNamespace(force=force, deflection=deflection,
                                    weight=np.ones_like(force)),
        noise=noise)
    return types.SimpleNamespace(problem=problem, free_values=theta, residual=residual,
                                 jacobian=design / noise)


def test_blocked_cross_validation_equals_refitting_each_fold():
    """For a linear model the case-deletion formula is exact: the blocked cross-validated
    error equals refitting without each fold and predicting it."""
    rng = np.random.default_rng(1)
    curves, points = 5, 12
    deflection = np.tile(np.linspace(0.01, 0.1, points), (curves, 1))
    slope = np.repeat(np.eye(curves), points, axis=0) * deflection.reshape(-1)[:, None]
    design = np.column_stack([slope, deflection.reshape(-1) ** 2])  # per-curve slope + shared
    force = (design @ rng.uniform(1, 2, design.shape[1])).reshape(curves, points)
    force += 0.5 * rng.standard_normal(force.shape)
    result = _linear_fit(design, force, deflection)
    cv = ft.blocked_cross_validation(result)
    folds = fold_of_points(result.problem, cv.folds).reshape(-1)
    assert set(np.unique(folds)) == set(range(cv.folds))
    for k in range(cv.folds):  # every fold keeps every curve
        assert all((folds.reshape(curves, points)[c] != k).any() for c in range(curves))
    squares = 0.0
    for k in range(cv.folds):
        keep = folds != k
        theta = np.linalg.lstsq(design[keep], force.reshape(-1)[keep], rcond=None)[0]
        squares += float(np.sum((design[~keep] @ theta - force.reshape(-1)[~keep]) ** 2))
    assert cv.valid
    assert cv.rmse_N == pytest.approx(np.sqrt(squares / force.size), rel=1e-9)


def test_cross_validation_is_not_used_when_a_fold_leaves_a_parameter_undetermined():
    """A parameter seen only by a few points of one curve (a curve of two points): a fold
    that holds them out cannot determine it, the leverage says so, and the value is nan
    with words instead of a meaningless number."""
    rng = np.random.default_rng(2)
    deflection = np.tile(np.linspace(0.01, 0.1, 8), (3, 1))
    column = np.zeros(24)
    column[[22, 23]] = 1.0  # only the last two points of the last curve see it
    design = np.column_stack([deflection.reshape(-1), column])
    force = (design @ np.array([100.0, 3.0])).reshape(3, 8) + 0.5 * rng.standard_normal((3, 8))
    cv = ft.blocked_cross_validation(_linear_fit(design, force, deflection))
    assert not cv.valid and np.isnan(cv.rmse_N)
    assert cv.largest_leverage > 0.99 and "not determined by the rest" in cv.words


def test_an_implausible_size_is_named_with_its_range_and_source():
    words = implausible_words(ft.SelfWeight, ("self_weight.mass_per_length",),
                              {"self_weight.mass_per_length": 3.2})
    assert len(words) == 1
    assert "self_weight explains it only at mass_per_length = 3.2 kg/m" in words[0]
    assert "something else is likely missing" in words[0] and "kite" in words[0]
    assert not implausible_words(ft.SelfWeight, ("self_weight.mass_per_length",),
                                 {"self_weight.mass_per_length": 0.3})
    for effect in ft.BUILT_IN_EFFECTS.values():  # every built-in states a range and source
        for parameter in effect.parameters:
            assert parameter.plausible is not None and parameter.plausible_source


def test_likelihood_ratio_boundary_mixture():
    """One parameter at a bound: half the chi^2_1 tail (Self & Liang 1987); interior: the
    chi^2_q tail; no improvement: p = 1."""
    import scipy.stats

    assert ft.likelihood_ratio_p_value(0.0, 1, 1) == 1.0
    assert ft.likelihood_ratio_p_value(6.635, 1, 1) == pytest.approx(0.005, rel=1e-3)
    assert ft.likelihood_ratio_p_value(6.635, 1, 0) == pytest.approx(0.01, rel=1e-3)
    two = ft.likelihood_ratio_p_value(9.0, 2, 1)
    assert two == pytest.approx(0.5 * scipy.stats.chi2.sf(9.0, 1)
                                + 0.5 * scipy.stats.chi2.sf(9.0, 2), rel=1e-12)
    with pytest.raises(ValueError, match="at_bound"):
        ft.likelihood_ratio_p_value(1.0, 1, 2)


def _refit_stub(outcomes, calls):
    """A stand-in for ``fit_problem``: the refit from ``start`` ends at ``outcomes[start]``
    ``(vector, chi2)``; ``calls`` records the starts."""

    def fit_problem(problem, options):
        start = tuple(float(v) for v in problem.start)
        calls.append(start)
        vector, chi2 = outcomes[start]
        residual = np.array([np.sqrt(chi2)])
        return types.SimpleNamespace(
            vector=np.array(vector, float), residual=residual, jacobian=np.zeros((1, 2)),
            problem=types.SimpleNamespace(batch=types.SimpleNamespace(force=np.zeros(1))))

    return fit_problem


def _box_problem():
    """Two radius-scaling exponents, null 0 inside the box [-4, 4]."""
    problem = types.SimpleNamespace(
        names=("radius_scaling.curvature_radius_excess", "radius_scaling.moment_radius_excess"),
        base=np.zeros(2), lower=np.full(2, -4.0), upper=np.full(2, 4.0), free_names=())
    problem.with_free = lambda names, start: types.SimpleNamespace(start=np.asarray(start))
    return problem


def test_a_refit_at_the_edge_of_its_box_is_repeated_from_the_typical_size(monkeypatch):
    """From the null the refit ends at the box's edge (+4, another basin): it is repeated
    from the typical size (-3, the tension-field tube's) and the better refit is kept; a
    refit that ends inside the box is not repeated."""
    from fitting._diagnose import selection

    problem, names = _box_problem(), _box_problem().names
    typical = tuple(p.typical for p in ft.RadiusScaling.parameters)
    assert typical[0] == -3.0
    calls = []
    monkeypatch.setattr(selection, "fit_problem", _refit_stub(
        {(0.0, 0.0): ((4.0, 0.2), 100.0), typical: ((-3.1, 0.0), 10.0)}, calls))
    refit, failure = selection.refit_candidate(problem, names, ft.RadiusScaling, None)
    assert calls == [(0.0, 0.0), typical] and not failure
    assert refit.vector[0] == pytest.approx(-3.1)
    calls.clear()
    monkeypatch.setattr(selection, "fit_problem", _refit_stub(
        {(0.0, 0.0): ((-2.6, 0.1), 12.0)}, calls))
    refit, _ = selection.refit_candidate(problem, names, ft.RadiusScaling, None)
    assert calls == [(0.0, 0.0)] and refit.vector[0] == pytest.approx(-2.6)
