"""The TU Delft V3 kite hung and scored in CI (issues 14 and 15), on ONE compiled program:
the hang of ``experiments/v3_hanging_test.py`` (the committed calibration, case 1: gravity at
0.15 bar) is compiled once per process and shared by every test here (a module fixture),
including the script's quick mode and its ``predict`` contract.

- the hung kite is in equilibrium: converged, the suspension reactions equal the weight
  (forces and moments), every line's and rope's state reported, held and suspension nodes
  where the model holds them;
- ``score --quick`` reproduces the peers' undeformed score and the committed calibration's
  own RMS; ``predict`` writes every node and the timing summary;
- the 12 measured lengths are defined as kite_fem defines them.

Data: experiments/data/v3_hanging ("Structural model data from awegroup/kite_fem (MIT, (c)
2025 Patrick Roeleveld); marker data from pimjhaanen/photogrammetry_thesis (MIT, (c) 2026
PJ Haanen)").
"""

import csv
import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

import jaxtube as jt

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"
KITE_FEM = EXPERIMENTS / "data" / "v3_hanging" / "kite_fem"
HELD = [0, 72, 81, 106, 115, 127, 128, 129]
MASS_KG = 12.859159


@pytest.fixture(scope="module")
def script():
    sys.path.insert(0, str(EXPERIMENTS))
    spec = importlib.util.spec_from_file_location("v3_hanging_test",
                                                  EXPERIMENTS / "v3_hanging_test.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def case1(script):
    """Case 1 hung with the committed calibration (this compiles the shared program)."""
    calibration = json.loads(script.CALIBRATION.read_text())
    pressure, centre, tip, _ = script.CASES[1]
    return script.solve_case(pressure, centre, tip, calibration["bending_scale"], repeat=False,
                             law_form=calibration.get("law_form", "moment"),
                             trailing_edge_factor=calibration.get("trailing_edge_factor", 1.0))


def test_trailing_edge_factor_scales_the_trailing_edge_springs_alone(script):
    """The calibration's second number acts on the 28 springs that join neighbouring
    trailing-edge nodes (kite_fem's even wing nodes 2, 4, ..., 58), tip to tip, and on no
    other line: their rest lengths (the model file's straight distances) times the factor."""
    model = importlib.import_module("_v3_model")  # on the path since the script's fixture
    imported = model.import_case(0.15)
    rows = model.trailing_edge_rows(imported.model)
    nodes = np.sort(imported.model.spring_nodes[rows], axis=1)
    assert len(rows) == 28
    assert sorted(map(tuple, nodes.tolist())) == [(n, n + 2) for n in range(2, 58, 2)]
    position = imported.model.node_position
    before = np.asarray(imported.params.elements.line_rest_length)
    np.testing.assert_allclose(before[rows], np.linalg.norm(
        position[nodes[:, 0]] - position[nodes[:, 1]], axis=1), rtol=1e-6)
    after = np.asarray(model.with_trailing_edge_factor(imported, 0.9)
                       .params.elements.line_rest_length)
    others = np.setdiff1d(np.arange(before.size), rows)
    np.testing.assert_array_equal(after[others], before[others])
    np.testing.assert_allclose(after[rows], 0.9 * before[rows], rtol=1e-15)
    assert model.with_trailing_edge_factor(imported, 1.0) is imported
    with pytest.raises(ValueError, match="trailing_edge_factor"):
        model.with_trailing_edge_factor(imported, 0.0)


def test_measured_length_definitions_reproduce_kite_fem(script):
    """The 12 lengths as defined here give kite_fem's own model_results.csv from its solved
    states (so La..Li, b, LcsTL/TR are what the validation data measure)."""
    with open(KITE_FEM / "model_results.csv", newline="") as file:
        published = {int(r["Load case"]): [float(r[n]) for n in script.LENGTH_NAMES]
                     for r in csv.DictReader(file)}
    for case in (1, 3, 5):
        state = np.load(KITE_FEM / "states" / f"load_case_{case}.npz")
        lengths = script.measured_lengths(state["coords_current"].reshape(-1, 3))
        np.testing.assert_allclose(lengths, published[case], rtol=1e-9)


def test_v3_hangs_in_equilibrium(case1):
    imported, solution = case1["imported"], case1["solution"]
    jt.check_converged(solution, "V3 hang")
    assert case1["converged"]
    # Reactions equal the weight, forces and moments (final stage: full gravity).
    balance = jt.weight_and_reactions(imported, solution)
    weight = MASS_KG * 9.81
    assert balance["total_mass_kg"] == pytest.approx(MASS_KG, abs=1e-5)
    np.testing.assert_allclose(balance["weight_and_loads_N"], [0.0, 0.0, weight], rtol=1e-6,
                               atol=1e-9)
    np.testing.assert_allclose(balance["reaction_sum_N"], [0.0, 0.0, -weight],
                               atol=1e-6 * weight)
    np.testing.assert_allclose(balance["reaction_moment_Nm"], -balance["applied_moment_Nm"],
                               atol=1e-5 * weight)
    # Every spring and rope reported, taut or slack; the bridle carries the kite.
    rows = jt.kite_fem_line_table(imported, solution)
    assert len(rows) == 664 + 14 and {r["state"] for r in rows} <= {"taut", "slack"}
    bridle = [r for r in rows if r["element"] == "bridle"]
    assert len(bridle) == 46 and sum(r["state"] == "taut" for r in bridle) >= 20
    assert all(r["tension_N"] > 0 for r in bridle if r["state"] == "taut")
    assert all(r["tension_N"] == 0.0 for r in rows if r["state"] == "slack"
               and r["length_m"] < r["rest_length_m"] * (1 - 1e-4))
    # Held nodes stay, the suspension holds, the kite sags.
    positions = case1["positions"]
    reference = imported.model.node_position
    np.testing.assert_array_equal(positions[HELD], reference[HELD])
    np.testing.assert_allclose(positions[[82, 116]], reference[[82, 116]], atol=1e-9)
    assert np.linalg.norm(positions - reference, axis=1).max() > 0.1


def test_quick_score_and_predict(script, case1, tmp_path):
    calibration = json.loads(script.CALIBRATION.read_text())
    assert script.main(["score", "--quick", "--no-figures", "--out", str(tmp_path)]) == 0
    result = json.loads((tmp_path / "v3_hanging_test.json").read_text())
    case = result["cases"]["1"]
    assert case["converged"]
    # The null model reproduces the peers' published undeformed score (695 mm).
    assert abs(case["undeformed_rms_mm"] - 695) <= 5
    # The committed calibration reproduces its own RMS, and beats the undeformed kite.
    assert abs(case["rms_mm"] - calibration["rms_mm"]) <= 1.0
    assert case["rms_mm"] < 0.5 * case["undeformed_rms_mm"]
    assert (tmp_path / "v3_hanging_test.txt").read_text().startswith("TU Delft V3")

    out = tmp_path / "predict"
    code = script.main(["predict", "--pressure-bar", "0.15", "--centre-load-kg", "0",
                        "--tip-load-kg", "0", "--out", str(out)])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["converged"] is True
    assert summary["seconds"] > 0 and summary["compile_seconds"] > 0
    assert summary["calibration"] == "experiments/results/v3_calibration.json"
    assert summary["trailing_edge_factor"] == calibration["trailing_edge_factor"]
    with open(out / "positions.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    assert [int(r["node"]) for r in rows] == list(range(247))
    positions = np.asarray([[float(r[k]) for k in ("x_m", "y_m", "z_m")] for r in rows])
    np.testing.assert_allclose(positions, case1["positions"], atol=1e-9)
    np.testing.assert_allclose(script.measured_lengths(positions),
                               list(case["lengths_m"].values()), rtol=1e-9)
