"""The diagnosis' decision pieces on constructed inputs (no model, no compilation): the
blocked cross-validation against brute-force refits, its validity check, plausible sizes,
the boundary mixture, the refit's second start, and the evidence measured against the residual
scatter when the model still misses."""

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
            convergence=types.SimpleNamespace(message="decrease of the loss below tolerance"),
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
    refit that ends inside the box past the typical size is not repeated."""
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
        {(0.0, 0.0): ((-3.4, 0.3), 12.0)}, calls))
    refit, _ = selection.refit_candidate(problem, names, ft.RadiusScaling, None)
    assert calls == [(0.0, 0.0)] and refit.vector[0] == pytest.approx(-3.4)


def test_a_refit_that_stops_short_of_the_typical_size_is_repeated_from_it(monkeypatch):
    """From the null the refit stalls inside the box, short of the typical size (a local
    minimum on the way, or a small effect: the null start alone cannot tell): it is repeated
    from the typical size and the lower chi^2 is kept, whichever start gave it."""
    from fitting._diagnose import selection

    problem, names = _box_problem(), _box_problem().names
    typical = tuple(p.typical for p in ft.RadiusScaling.parameters)
    for from_typical, expected in ((((-3.1, -2.9), 10.0), -3.1), (((-0.5, 0.0), 40.0), -0.2)):
        calls = []
        monkeypatch.setattr(selection, "fit_problem", _refit_stub(
            {(0.0, 0.0): ((-0.2, 0.1), 30.0), typical: from_typical}, calls))
        refit, failure = selection.refit_candidate(problem, names, ft.RadiusScaling, None)
        assert calls == [(0.0, 0.0), typical] and not failure
        assert refit.vector[0] == pytest.approx(expected)


def _ranked_against(chi2_now: float, chi2_refit: float, monkeypatch, points: int = 100):
    """``rank_candidates`` on one candidate (reinforcement) whose refit lowers chi^2 from
    ``chi2_now`` to ``chi2_refit`` (noise units, ``points`` points, one law coordinate
    fitted); the refit, score test and cross-validation are stand-ins."""
    from fitting._diagnose import ranking

    names = ("law.A", "reinforcement.stiffness")

    def fit(chi2, free, vector):
        residual = np.full(points, np.sqrt(chi2 / points))
        problem = types.SimpleNamespace(
            names=names, free_index=free, base=np.zeros(2), lower=np.array([-np.inf, 0.0]),
            upper=np.array([np.inf, 500.0]), free_names=[names[i] for i in free],
            batch=types.SimpleNamespace(force=np.zeros(points), weight=np.ones(points)))
        problem.with_free = lambda free_names, start: problem
        return types.SimpleNamespace(problem=problem, residual=residual, vector=vector,
                                     jacobian=np.zeros((points, 2)), rmse=1.0, noise=1.0)

    current = fit(chi2_now, (0,), np.zeros(2))
    refit = fit(chi2_refit, (0, 1), np.array([0.0, 15.0]))
    monkeypatch.setattr(ranking, "refit_candidate", lambda *args: (refit, ""))
    monkeypatch.setattr(ranking, "score_test", lambda *args: types.SimpleNamespace(
        statistic=0.0, p_value=1.0))
    monkeypatch.setattr(ranking, "absorbed_free_effects", lambda result, candidates: {
        c.name: (np.ones(1), np.ones(1)) for c in candidates})
    invalid = types.SimpleNamespace(valid=False, rmse_N=np.nan, words="not valid",
                                    rise_z=lambda other: np.nan)
    monkeypatch.setattr(ranking, "blocked_cross_validation", lambda result: invalid)
    rows, _ = ranking.rank_candidates(current, [ft.Reinforcement],
                                      ft.DiagnoseOptions(progress=False))
    return rows[0]


def test_evidence_is_measured_against_the_residual_scatter_when_the_model_misses(monkeypatch):
    """The same chi^2 drop of 20 (noise units) is evidence when the refit's residuals are
    the noise (chi^2 / dof < 1: c = 1, LR = 20, added) and is not when the refit still
    misses (chi^2 / dof = 280 / 98 = 2.86: any flexibility gains that much per parameter;
    LR = 20 / 2.86 = 7.0, BIC drop 7.0 - ln 100 = 2.4 < 10)."""
    good = _ranked_against(115.0, 95.0, monkeypatch)
    assert good.dispersion == 1.0 and good.lr_statistic == pytest.approx(20.0)
    assert good.significant and good.delta_bic == pytest.approx(-20 + np.log(100))
    missing = _ranked_against(300.0, 280.0, monkeypatch)
    assert missing.dispersion == pytest.approx(280.0 / 98)
    assert missing.lr_statistic == pytest.approx(20.0 * 98 / 280)
    assert missing.delta_bic == pytest.approx(-20.0 * 98 / 280 + np.log(100))
    assert missing.delta_chi2 == pytest.approx(-20.0)  # the raw drop is kept
    assert not missing.significant and "BIC" in missing.decided_by
    assert any("residual scatter, c = 2.86" in reason for reason in missing.reasons)


def _linear_lm(monkeypatch, start, **options):
    """Levenberg-Marquardt on a linear least-squares stand-in (no model): a line through
    four points whose best slope, -0.5, is below the slope's lower bound 0; returns
    ``(x, report, the intercept's optimum with the slope on its bound)``."""
    from fitting._calibrate import problem as calibration

    design = np.array([[1.0, 1.0], [1.0, 2.0], [1.0, 3.0], [1.0, 4.0]])
    target = np.array([2.0, 1.5, 1.0, 0.5])

    def residuals_and_jacobian(vector, *args, **kwargs):
        converged = np.ones(4, bool)
        return design @ np.asarray(vector) - target, design, types.SimpleNamespace(
            converged=converged, force=np.zeros(4))

    monkeypatch.setattr(calibration, "_residuals_and_jacobian", residuals_and_jacobian)
    problem = types.SimpleNamespace(
        batch=types.SimpleNamespace(force=np.zeros(4), mask=np.ones(4, bool)),
        free_index=(0, 1), free_bounds=(np.array([-np.inf, 0.0]), np.array([np.inf, 5.0])),
        free_names=["intercept", "slope"], effect_names=("slope",), static=dict,
        full=lambda x: np.asarray(x),
        residual_args=lambda robust=None: ())
    fit_options = ft.FitOptions(progress=False, chi2_tol=0.05, ftol=1e-9, **options)
    x, _, report = calibration._levenberg_marquardt(problem, np.asarray(start, float),
                                                    fit_options)
    return x, report, target.mean()


def test_a_coordinate_held_on_its_bound_costs_no_rejected_steps(monkeypatch):
    """The slope starts on its lower bound (a null) with the descent direction pointing out
    of the box, the intercept off its optimum: the slope is held (active set), the intercept
    reaches its constrained optimum in a few evaluations (before: the coupled step was
    clipped and rejected again and again, one evaluation each, and the fit stopped at 1.46
    instead of the optimum 1.25, the damping having shrunk every step to nothing)."""
    x, report, optimum = _linear_lm(monkeypatch, [0.0, 0.0])
    assert x[1] == 0.0 and x[0] == pytest.approx(optimum, rel=1e-6)
    assert report["converged"] and report["evaluations"] <= 4, report["evaluations"]


def test_a_start_that_comes_back_to_its_bound_ends_there(monkeypatch):
    """From a slope of 3 (a "typical" start) the fit walks the slope back to its bound;
    watched (``stop_on_bound``), it ends as soon as the active set holds it there, and not
    otherwise."""
    from fitting._calibrate.outcome import FitOutcome

    x, report, _ = _linear_lm(monkeypatch, [0.0, 3.0], stop_on_bound=("slope",))
    assert x[1] == 0.0 and report["message"] == FitOutcome[FitOutcome.back_on_bound]
    x, report, optimum = _linear_lm(monkeypatch, [0.0, 3.0])
    assert report["message"] != FitOutcome[FitOutcome.back_on_bound]
    assert x[1] == 0.0 and x[0] == pytest.approx(optimum, rel=1e-3)


class _HeldProblem:
    """A stand-in problem with two fitted coordinates and two held since the baseline."""

    names = ["A1", "B1", "A2", "B2"]

    def __init__(self, free=("A1", "B1")):
        self.free_names = list(free)
        self.free_index = tuple(self.names.index(n) for n in free)

    def with_free(self, names, vector):
        return _HeldProblem(names)


def _release(monkeypatch, chi2_after, errors):
    """:func:`release_held` from a model at chi^2 = 200 (100 points) with ``A2``, ``B2``
    held; a refit with the free set ``S`` ends at ``chi2_after[S]`` with standard errors
    ``errors[S]`` (inf: undetermined)."""
    from fitting._diagnose import selection

    def result(problem, chi2_value, se):
        return types.SimpleNamespace(problem=problem, vector=np.arange(4.0), rmse=chi2_value,
                                     chi2=chi2_value, free_standard_errors=se)

    def fit_problem(problem, options):
        key = frozenset(problem.free_names)
        return result(problem, chi2_after[key], [errors[key].get(n, 0.1)
                                                 for n in problem.free_names])

    monkeypatch.setattr(selection, "fit_problem", fit_problem)
    monkeypatch.setattr(selection, "chi2", lambda r: r.chi2)
    monkeypatch.setattr(selection, "dispersion",
                        lambda r: r.chi2 / (100 - len(r.problem.free_index)))
    current = result(_HeldProblem(), 200.0, [0.1, 0.1])
    return selection.release_held(current, ["A2", "B2"], None, 100), current


def test_coordinates_held_since_the_baseline_are_freed_once_the_model_determines_them(
        monkeypatch):
    """With both held coordinates freed, ``A2`` is determined and ``B2`` is not: ``A2`` alone
    is refitted and kept free when the BIC falls (chi^2 200 -> 150, one coordinate more:
    gain 50 / c - ln 100 > 0); kept held when it does not pay (200 -> 198), and untouched
    when neither is determined."""
    inf = float("inf")
    both, alone = frozenset(["A1", "B1", "A2", "B2"]), frozenset(["A1", "B1", "A2"])
    chi2_after = {both: 149.0, alone: 150.0}
    errors = {both: {"B2": inf}, alone: {}}
    (model, released, words), _ = _release(monkeypatch, chi2_after, errors)
    assert released == ["A2"] and model.problem.free_names == ["A1", "B1", "A2"]
    assert "freed again" in words[0] and "RMSE 200 -> 150" in words[0]

    (model, released, words), current = _release(
        monkeypatch, {both: 197.0, alone: 198.0}, errors)
    assert released == [] and model is current and "does not pay" in words[0]

    (model, released, words), current = _release(
        monkeypatch, {both: 150.0}, {both: {"A2": inf, "B2": inf}})
    assert released == [] and model is current and words == []


def test_the_refined_law_starts_on_the_current_one():
    """:func:`refined_start` splits the last unwrinkled and the last wrinkled increment at
    their middle curvature: at the reference specimen the refined law's pivots are the
    current ones plus two midpoints whose moments are the current law's there; exponents
    and effect parameters carry over."""
    from fitting._bench.scaling import PivotScaling
    from fitting._diagnose.refinement import refined_scaling, refined_start

    coarse = PivotScaling(pivots_per_regime=(1, 1, 1))
    fine = refined_scaling(coarse)
    assert fine.pivots_per_regime == (2, 2, 1)
    p_ref, r_ref = 2.0e4, 0.07
    # log of the increments at the reference (kappa, then M), exponents B
    vector = np.array([np.log(0.2), np.log(1.5), np.log(4.0), 1.0, 0.9, 1.1,
                       np.log(30.0), np.log(25.0), np.log(4.0), 1.0, 1.05, 0.95, 7e-5])
    effect = ["shear.flexibility"]
    current = types.SimpleNamespace(
        vector=vector, problem=types.SimpleNamespace(
            scaling=coarse, reference=(p_ref, r_ref), names=coarse.names() + effect,
            effect_names=tuple(effect)))
    problem = types.SimpleNamespace(scaling=fine, names=fine.names() + effect,
                                    effect_names=tuple(effect),
                                    base=np.zeros(len(fine.names()) + 1))
    start = refined_start(current, problem)
    law = coarse.law(vector[:12], p_ref, r_ref)
    (log_k, b_k), (log_m, b_m) = fine._split(start[:20])
    curvatures, moments = np.cumsum(np.exp(log_k)), np.cumsum(np.exp(log_m))
    assert curvatures[[1, 3, 4]] == pytest.approx(np.cumsum([0.2, 1.5, 4.0]), rel=1e-12)
    assert moments[[1, 3, 4]] == pytest.approx(np.cumsum([30.0, 25.0, 4.0]), rel=1e-12)
    assert curvatures[[0, 2]] == pytest.approx([0.1, 0.2 + 0.75], rel=1e-12)
    for k in (0, 2):
        assert moments[k] == pytest.approx(float(law.moment(curvatures[k], p_ref, r_ref)),
                                           rel=1e-12)
    assert list(b_k) == [1.0, 1.0, 0.9, 0.9, 1.1] and list(b_m) == [1.0, 1.0, 1.05, 1.05, 0.95]
    assert start[-1] == 7e-5


def test_lengths_within_twenty_percent_are_not_called_a_single_length():
    """Curves at 1.0 and 1.2 m do not vary the length enough to separate a compliance (the
    ratio must exceed 1.2), and the advice says so without calling them one length."""
    from fitting._diagnose.separation import _spread_words

    def curve(name, length):
        return ft.MeasuredCurve(name=name, setup="cantilever_tip", pressure=2e4, radius=0.1,
                                length=length, deflection=np.array([0.01, 0.02]),
                                force=np.array([1.0, 2.0]))

    data = ft.MeasuredData((curve("a", 1.0), curve("b", 1.0), curve("c", 1.2)))
    varied, fixed = _spread_words(data, ("length", "radius"))
    assert varied == []
    assert fixed == ["the data's lengths differ by 20 % or less (1-1.2 m)",
                     "the data have a single radius (100 mm)"]
    varied, _ = _spread_words(ft.MeasuredData((curve("a", 1.0), curve("c", 1.25))), ("length",))
    assert varied == ["length"]
