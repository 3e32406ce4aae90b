"""The diagnosis you can trust (issue 34). No result is lost: documents with ``null`` for
every non-finite number; each output written on its own; exit status 0 with a converged
final model, 1 without. And the simulation study's machinery: designs diagnosed on a local
Dask cluster of two workers, stored as they end (a second run computes nothing), and tables
that account for every design (the study itself, ``experiments/diagnosis_study.py``, is not a
test; its ``--quick`` dozen takes too long for CI, so a two-design variant of the same
functions runs here).

Data: ``tests/data/diagnosis/three_radii_no_cv.csv``, made by the independent continuum
solver through the study's generator (``fitting.make_design_data`` of ``StudyDesign(index=0,
seed=7, specimens=((0.2, 0.05, 1.2), (0.2, 0.075, 1.2), (0.2, 0.1, 1.2)), points=8,
noise_force_N=0.05, noise_deflection_mm=0.02)``: a tension-field tube, nothing hidden). Three
curves of eight points at three radii: too few for the blocked cross-validation (a fold's
leverage is 0.94), so its error is undefined (NaN), which once crashed the command at its
very end. The model is small (6 segments, two candidates) and its compiled program is
shared by every diagnosis of this file (same shape, same model).
"""

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

import fitting as ft
from fitting._cli import diagnose as diagnose_command
from fitting._cli import main

DATA = Path(__file__).parent / "data" / "diagnosis" / "three_radii_no_cv.csv"
CANDIDATES = ("radius_scaling", "self_weight")
ARGS = ["--quiet", "--segments", "6", "--candidates", ",".join(CANDIDATES)]
THREE_RADII = ((0.2, 0.05, 1.2), (0.2, 0.075, 1.2), (0.2, 0.1, 1.2))


def strict_json(path: Path):
    """The document at ``path``; NaN or infinity (not JSON) is an error."""
    def refuse(constant):
        raise ValueError(f"{path}: {constant} is not JSON")
    return json.loads(path.read_text(), parse_constant=refuse)


def test_write_json_turns_nan_and_infinity_anywhere_into_null(tmp_path):
    document = {"a": math.nan, "b": [1.0, math.inf, (-math.inf, 2)],
                "c": {"d": np.float64("nan"), "e": np.array([1.0, np.nan]),
                      "f": np.float32(np.inf), "g": np.int64(3), "h": np.bool_(True)},
                "i": (np.array([[np.nan, 0.5]]),), 4: "key made a string", "j": None}
    ft.write_json(tmp_path / "doc.json", document)
    assert strict_json(tmp_path / "doc.json") == {
        "a": None, "b": [1.0, None, [None, 2]],
        "c": {"d": None, "e": [1.0, None], "f": None, "g": 3, "h": True},
        "i": [[[None, 0.5]]], "4": "key made a string", "j": None}
    with pytest.raises(TypeError, match="not JSON serialisable: object"):
        ft.json_ready({"x": object()})


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory):
    """One run of ``jaxtube diagnose`` on the three-radii data, with the Diagnosis it made."""
    out = tmp_path_factory.mktemp("diagnose") / "out"
    made = []
    original = diagnose_command.diagnose

    def keep(*args, **kwargs):
        made.append(original(*args, **kwargs))
        return made[-1]

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(diagnose_command, "diagnose", keep)
        code = main(["diagnose", str(DATA), "--out", str(out), *ARGS])
    return code, out, made[0]


def test_too_few_curves_for_cross_validation_is_diagnosed_end_to_end(diagnosed):
    code, out, _ = diagnosed
    assert code == 0
    document = strict_json(out / "diagnosis.json")
    assert document["output_failures"] == {}
    assert document["baseline"]["cv_rmse_N"] is None  # undefined, written as null
    assert document["final"]["converged"] is True
    assert any("Cross-validation left out" in s for s in document["statements"])
    assert math.isfinite(document["noise_N"]) and document["final"]["rmse_N"] > 0
    strict_json(out / "parameters.json")
    assert "verdict: " in (out / "report.txt").read_text()
    for name in ("fit_0_baseline.png", "where_it_fails.png", "ranking.png",
                 "before_after.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name


def test_a_failing_writer_loses_only_its_own_file(diagnosed, tmp_path, monkeypatch, capsys):
    _, _, diagnosis = diagnosed

    def broken(diagnosis):
        raise RuntimeError("no room for the bars")

    monkeypatch.setattr(diagnose_command, "ranking_figure", broken)
    out = tmp_path / "out"
    failures = diagnose_command.write_outputs(out, diagnosis, diagnosis.to_json())
    assert failures == {"ranking.png": "RuntimeError: no room for the bars"}
    assert "could not write ranking.png: RuntimeError: no room" in capsys.readouterr().err
    assert not (out / "ranking.png").exists()
    assert strict_json(out / "diagnosis.json")["output_failures"] == failures
    for name in ("report.txt", "parameters.json", "fit_0_baseline.png", "before_after.png"):
        assert (out / name).stat().st_size > 0, name


def test_exit_status_is_1_only_when_the_final_model_did_not_converge(diagnosed, tmp_path,
                                                                     monkeypatch, capsys):
    _, _, diagnosis = diagnosed
    assert not diagnosis.steps  # the final model is the baseline
    stalled = dataclasses.replace(diagnosis.baseline.convergence, converged=False,
                                  message="iteration cap reached")
    unconverged = dataclasses.replace(
        diagnosis, baseline=dataclasses.replace(diagnosis.baseline, convergence=stalled))
    monkeypatch.setattr(diagnose_command, "diagnose", lambda *args, **kwargs: unconverged)
    out = tmp_path / "out"
    assert main(["diagnose", str(DATA), "--out", str(out), *ARGS]) == 1
    assert "FINAL MODEL DID NOT CONVERGE (iteration cap reached)" in capsys.readouterr().out
    assert strict_json(out / "diagnosis.json")["final"]["converged"] is False


def _rate_or_none(value) -> bool:
    return value is None or 0.0 <= value <= 1.0


def test_study_on_a_local_cluster_of_two_workers_accounts_for_every_design(tmp_path):
    """Two tiny designs (the shape of the data above: three curves of eight points), one with
    nothing hidden and one with self-weight over two lengths and two pressures, on a local
    cluster of two workers (threads of this process, so the compiled model is shared)."""
    designs = [ft.StudyDesign(index=0, seed=7, specimens=THREE_RADII, points=8,
                              noise_force_N=0.05, noise_deflection_mm=0.02),
               ft.StudyDesign(index=1, seed=7, specimens=((0.2, 0.05, 1.2), (0.3, 0.075, 0.8),
                                                          (0.2, 0.1, 0.8)),
                              points=8, noise_force_N=0.05, noise_deflection_mm=0.02,
                              hidden=(("self_weight", 0.5),))]
    assert designs[1].separable("self_weight") and not designs[0].separable("self_weight")
    with ft.open_cluster_client(workers=2, processes=False) as client:
        assert len(client.scheduler_info()["workers"]) == 2
        records, ran = ft.run_study(designs, tmp_path, client, progress=False,
                                    candidates=CANDIDATES, segments=6)
        again, ran_again = ft.run_study(designs, tmp_path, client, progress=False,
                                        candidates=CANDIDATES, segments=6)
    assert ran == 2 and ran_again == 0 and again == records
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"{d.name}.json" for d in designs]
    assert [r["name"] for r in records] == [d.name for d in designs]
    assert all(r["error"] is None for r in records), [r.get("traceback") for r in records]
    assert records[1]["snr"]["self_weight"] > 0 and records[1]["separable"]["self_weight"]
    summary = ft.study_summary(records)
    assert summary["designs"] == summary["diagnosed"] + summary["failed"] == 2
    assert sum(map(sum, summary["confusion"]["counts"])) == summary["diagnosed"]
    assert summary["confusion"]["hidden"] == ["none", "self_weight"]
    assert summary["false_alarm"]["nulls"] == 1
    assert sum(row["effects"] for row in summary["power"]) == 1
    rates = [summary["false_alarm"]["rate"], summary["power_resolvable"]["found_clean"],
             summary["final_rmse_over_floor"]["within"], summary["noise_estimate_error"]["within"]]
    rates += [row[key] for row in summary["power"] for key in ("found", "found_clean")]
    assert all(_rate_or_none(rate) for rate in rates), rates
    for row, key in ((summary["false_alarm"], "rate"), (summary["final_rmse_over_floor"], "within"),
                     (summary["noise_estimate_error"], "within"),
                     (summary["power_resolvable"], "found_clean")):
        if row[key] is None:
            assert row["interval_95"] is None
        else:
            low, high = row["interval_95"]
            assert 0.0 <= low <= row[key] <= high <= 1.0 and high - low > 0.5  # two designs
    assert summary["seconds"]["median"] > 0 and summary["seconds"]["median_6_curves_warm"] is None
    report = ft.study_report(summary)
    assert "false alarms on null designs: " in report and "n/a" in report
    ft.write_json(tmp_path.parent / "summary.json", summary)
    strict_json(tmp_path.parent / "summary.json")
    ft.study_figure(records).savefig(tmp_path.parent / "study.png")
    assert (tmp_path.parent / "study.png").stat().st_size > 10_000


def test_study_rates_carry_their_exact_binomial_interval():
    """Clopper-Pearson against closed forms: with no hit the upper end solves
    ``(1 - p)^n = 0.025``, with every trial a hit the lower end ``p^n = 0.025``; one false
    alarm in 24 nulls reaches 21 % (the study page's figure), and the interval is centred
    on one half for half the trials."""
    from fitting._study.summary import rate_interval

    for n in (1, 10, 24, 300):
        assert rate_interval(0, n)[0] == 0.0
        assert rate_interval(0, n)[1] == pytest.approx(1.0 - 0.025 ** (1.0 / n), rel=1e-9)
        assert rate_interval(n, n)[0] == pytest.approx(0.025 ** (1.0 / n), rel=1e-9)
        assert rate_interval(n, n)[1] == 1.0
    low, high = rate_interval(1, 24)
    assert 0.001 < low < 0.0011 and high == pytest.approx(0.2112, abs=1e-4)
    low, high = rate_interval(50, 100)
    assert low == pytest.approx(1.0 - high, rel=1e-12) and 0.39 < low < 0.41
    assert rate_interval(0, 0) is None


def test_noise_only_records_match_the_estimate_the_diagnosis_uses():
    """The study's noise-only route (no diagnosis) sees the data as the diagnosis does: its
    order-2 estimate over the floor is the one of the committed CSV (read by
    ``load_measurements``), whose floor is the generator's."""
    design = ft.StudyDesign(index=0, seed=7, specimens=THREE_RADII, points=8,
                            noise_force_N=0.05, noise_deflection_mm=0.02)
    record = ft.noise_estimate_errors(design)
    floor = ft.make_design_data(design, with_snr=False).noise_floor_N
    assert record["noise_floor_N"] == floor
    expected = ft.estimate_noise(ft.load_measurements(DATA)) / floor - 1.0
    assert record["error_order_2"] == pytest.approx(expected, rel=1e-12)
    assert record["error_order_1"] != record["error_order_2"] != record["error_order_3"]
    assert all(0.0 <= record[f"ceiling_order_{k}"] <= 1.0 for k in (1, 2, 3))
    summary = ft.noise_summary([record, dict(record, error_order_3=None)])
    assert summary["order_3"]["designs"] == 1 and summary["order_2"]["designs"] == 2
    assert all(0.0 <= row["within"] <= 1.0 for row in summary.values())
    supported = record["ceiling_order_2"] >= 0.95
    assert summary["order_2"]["supported"] == 2 * supported
    assert (summary["order_2"]["within_supported"] is None) == (not supported)


def test_telling_the_two_compliances_apart_takes_three_lengths():
    """Shear (tip compliance ~ L) and clamp compliance (~ L^2) beside the bending (~ L^3):
    with the stiffness free, two lengths fit either compliance exactly, and the one not
    hidden reappears as a constant shift of 1 / EI. Solve the two-length case: the clamp
    model reproduces pure shear data at both lengths; at a third length it cannot."""
    lengths = np.array([0.6, 0.8, 1.0])
    shear, compliance_bending = 2e-4, 0.01  # tip compliance = a L^3 + s L  [m/N]
    truth = compliance_bending * lengths**3 + shear * lengths
    two = np.stack([lengths[:2]**3, lengths[:2]**2], axis=1)  # clamp model: a L^3 + c L^2
    fitted = np.linalg.solve(two, truth[:2])
    assert np.allclose(two @ fitted, truth[:2], rtol=1e-12)
    three = np.stack([lengths**3, lengths**2], axis=1)
    misfit = three @ np.linalg.lstsq(three, truth, rcond=None)[0] - truth
    assert np.max(np.abs(misfit)) > 1e-2 * shear * lengths.max()  # of the shear's own size

    def design(lengths):
        return ft.StudyDesign(index=0, seed=0, points=8, noise_force_N=0.1,
                              noise_deflection_mm=0.05,
                              specimens=tuple((0.2 + 0.1 * k, 0.075, length)
                                              for k, length in enumerate(lengths)))

    for effect in ("shear", "clamp_compliance"):
        assert not design((0.6, 1.2, 0.6)).separable(effect)
        assert design((0.6, 0.8, 1.2)).separable(effect)
    # Self-weight's preload needs two lengths only; 1.0 against 1.2 m is not varied (20 %).
    assert design((0.6, 1.2, 0.6)).separable("self_weight")
    assert not design((1.0, 1.2, 1.0)).separable("self_weight")


def test_the_sampling_ceiling_grows_with_the_points_a_design_has():
    """White noise at a design's deflections: 24 points (three curves of eight) leave the
    order-2 estimate outside 25 % of the realised noise often (15 windows of four points:
    its relative scatter is about 1 / sqrt(2 x 15) ~ 0.18 before the windows' overlap);
    600 points almost never."""
    from fitting._study.noise import _Curve, sampling_ceiling

    def curves(count, points):
        return [_Curve(np.linspace(0.0, 0.1, points) + 0.01 * k, np.zeros(points))
                for k in range(count)]

    small = sampling_ceiling(curves(3, 8), order=2)
    large = sampling_ceiling(curves(6, 100), order=2)
    assert 0.5 < small < 0.95 < large
    assert sampling_ceiling(curves(3, 3), order=2) is None  # too short for order 2


def test_when_every_coordinate_is_flagged_only_the_undetermined_directions_are_held(
        monkeypatch):
    """A study design (one pressure, large deflection noise) flagged every coordinate of its
    baseline as undetermined, and holding them all left nothing to fit ("ValueError: nothing
    to fit"). Then only one coordinate per direction the data do not see is held: here the
    third column is the sum of the first two (one such direction)."""
    from fitting._diagnose import selection

    rng = np.random.default_rng(0)
    columns = rng.standard_normal((12, 3))
    columns[:, 2] = columns[:, 0] + columns[:, 1]
    refits = []

    class Problem:
        free_names = ("a", "b", "c")
        free_index = (0, 1, 2)

        def with_free(self, names, vector):
            refits.append(tuple(names))
            return self

    fake = type("Result", (), {"problem": Problem(), "jacobian": columns * [1.0, 1e3, 2.0],
                               "free_standard_errors": np.full(3, np.inf), "vector": None})()
    monkeypatch.setattr(selection, "fit_problem", lambda problem, options: fake)
    held = selection.least_determined(fake)
    assert len(held) == 1 and held[0] in Problem.free_names
    _, still_held = selection.hold_undetermined_where_left(fake, None)
    assert still_held == held and refits == [tuple(n for n in "abc" if n not in held)]
    fake.jacobian[:, 2] += rng.standard_normal(12)  # determined: nothing is held
    assert selection.least_determined(fake) == []
    # An exponent at a single p r^3: its column is the rounding of the logarithms (1e-16 of
    # its pivot's log-a column, in no particular direction). Unit scaling must not make it
    # information (design_0_0070 of the study held every M[i].A instead and could not move).
    fake.jacobian[:, 2] = 1e-16 * (columns[:, 0] + rng.standard_normal(12))
    assert selection.least_determined(fake) == ["c"]


def test_the_refined_law_holds_what_the_current_model_holds():
    """A coordinate the current model holds (the data do not determine it: every exponent at
    a single ``p r^3``, the collapsed pivot) stays held in the refined law, split with its
    pivot, so the refinement's size and BIC count only what can move (design_0_0084 of the
    study, one specimen: 30 points against 20 coordinates kept the refinement out)."""
    import types

    from fitting._bench.scaling import PivotScaling
    from fitting._diagnose.refinement import refined_held, refined_scaling, split_parents

    coarse = PivotScaling(pivots_per_regime=(1, 1, 1))
    fine = refined_scaling(coarse)
    assert split_parents(coarse) == [0, 0, 1, 1, 2]
    assert split_parents(fine) == [0, 1, 1, 2, 3, 3, 4]
    free = ["kappa[1].A", "kappa[2].A", "M[1].A", "M[2].A"]
    current = types.SimpleNamespace(problem=types.SimpleNamespace(scaling=coarse,
                                                                  free_names=free))
    held = refined_held(current, fine)
    assert held == (["kappa[5].A"] + [f"kappa[{i}].B" for i in range(1, 6)] + ["M[5].A"]
                    + [f"M[{i}].B" for i in range(1, 6)])


def test_the_baseline_is_restarted_only_when_its_first_fit_ends_on_its_box(monkeypatch):
    """The baseline's first fit can end with the law's coordinates on the edges of their box
    (the study's design_0_0013: the collapse pivot's four, 7.6x the noise floor, against 4.7x
    from the best of six starts). Such a fit is restarted from perturbed guesses (the starts of
    ``FitOptions.multistart``) and the lowest chi^2 kept; a first fit inside its box is not,
    nor is any with one start. Constructed fits: no model is compiled."""
    import types

    from fitting._calibrate.fit import perturbed_starts
    from fitting._calibrate.problem import FitError
    from fitting._diagnose import restart

    class Problem:
        names = ("kappa[1].A", "kappa[1].B", "M[1].A", "shear.compliance")
        free_index = (0, 1, 2)
        free_names = ["kappa[1].A", "kappa[1].B", "M[1].A"]
        lower = np.array([-4.6, -1.0, -4.6, 0.0])
        upper = np.array([4.6, 4.0, 4.6, 1.0])

        def __init__(self, base):
            self.base = np.array(base, float)

        def with_free(self, names, vector):
            assert list(names) == self.free_names
            return Problem(vector)

        def full(self, free_values):
            vector = np.array(self.base, float)
            vector[list(self.free_index)] = free_values
            return vector

    def result(vector, cost):
        return types.SimpleNamespace(problem=Problem(vector), vector=np.array(vector, float),
                                     cost=cost)

    guess = [0.0, 1.0, 0.0, 0.0]
    costs = iter([50.0, 20.0, math.nan])  # restart 2 the best; restart 3's solves fail
    tried = []

    def fake_fit(problem, options):
        tried.append(problem.base[:3])
        cost = next(costs)
        if math.isnan(cost):
            raise FitError("the equilibrium solves did not converge")
        return result(problem.base, cost)

    monkeypatch.setattr(restart, "fit_problem", fake_fit)
    monkeypatch.setattr(restart, "chi2", lambda fit: fit.cost)
    options = types.SimpleNamespace(seed=0)
    inside = result([0.3, 1.2, -0.5, 0.0], 40.0)
    inside.problem = Problem(guess)
    assert restart.on_box_bounds(inside) == []  # the held shear at its null is not free
    assert restart.restart_on_box(inside, options, 4) == (inside, None) and not tried

    on_box = result([0.3, 4.0, -4.6, 0.0], 40.0)  # kappa[1].B at 4, M[1].A a factor 100 low
    on_box.problem = Problem(guess)
    assert restart.on_box_bounds(on_box) == ["kappa[1].B", "M[1].A"]
    assert restart.restart_on_box(on_box, options, 1) == (on_box, None) and not tried
    kept, report = restart.restart_on_box(on_box, options, 4)
    starts = perturbed_starts(Problem(guess), 3, 0)
    assert len(tried) == 3 and all(np.allclose(a, b) for a, b in zip(tried, starts))
    assert kept.cost == 20.0 and report.kept == 2 and report.chi2_gain == 20.0
    assert report.on_bounds == ("kappa[1].B", "M[1].A") and report.starts == 4
    assert report.start_chi2 == (40.0, 50.0, 20.0, math.inf)
    assert json.loads(json.dumps(report.to_json(), allow_nan=False))["start_chi2"][3] is None
    assert "restart 2 lowered chi^2 by 20" in report.words()
