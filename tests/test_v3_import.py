"""The TU Delft V3 kite imported from kite_fem (``initial.npz``, bundled with its licence in
``experiments/data/v3_hanging``): counts and mass, and the kite hung from nodes 82 and 116
under gravity through ``jaxtube simulate --kite-fem`` (one compiled program): converged,
suspension reactions equal to the weight (force and moment), every line's state reported,
every node written in kite_fem numbering."""

import csv
import json
from pathlib import Path

import numpy as np
import pytest

import jaxtube as jt
from fitting._cli.main import main

DATA = Path(__file__).parents[1] / "experiments" / "data" / "v3_hanging" / "kite_fem"
V3_MODEL = DATA / "initial.npz"


def test_v3_import_counts_and_mass():
    imported = jt.import_kite_fem(V3_MODEL, pressure_bar=0.15)
    structure, params = imported.structure, imported.params
    elements = structure.elements
    assert imported.model.node_count == 247
    assert structure.segment_count == 88 and len(structure.tube_names) == 11
    assert len(elements.line_ends) == 664 and len(elements.pulley_ends) == 14
    assert float(np.sum(params.elements.point_mass)) == pytest.approx(12.859, abs=5e-4)
    assert imported.held_nodes == (0, 72, 81, 106, 115, 127, 128, 129)
    assert structure.supports == ()  # the frame floats, held by its bridle
    assert len(elements.fixed_points) == 2
    # Every node mapped: 239 moving nodes, distinct jaxtube nodes; the tubes keep the
    # kite_fem positions and the pressure asked for.
    moving = imported.node_index[imported.node_index >= 0]
    assert moving.size == 239 and np.unique(moving).size == 239
    np.testing.assert_allclose(params.pressure, 0.15e5)
    reference = np.concatenate([np.asarray(params.node_position),
                                np.asarray(params.elements.point_position)])
    np.testing.assert_allclose(imported.kite_positions(reference), imported.model.node_position,
                               atol=1e-12)
    np.testing.assert_allclose(params.gravity, [0.0, 0.0, 9.81])


def test_v3_hangs_under_gravity(tmp_path):
    out = tmp_path / "v3"
    code = main(["simulate", "--kite-fem", str(V3_MODEL), "--pressure-bar", "0.15",
                 "--out", str(out), "--quiet"])
    summary = json.loads((out / "summary.json").read_text())
    assert code == 0 and summary["converged"], summary["steps"]
    weight = 12.859159 * 9.81
    np.testing.assert_allclose(summary["weight_and_loads_N"], [0.0, 0.0, weight], rtol=1e-6,
                               atol=1e-9)
    reaction = np.sum(list(summary["suspension_reactions_N"].values()), axis=0)
    np.testing.assert_allclose(reaction, [0.0, 0.0, -weight], atol=1e-6 * weight)
    np.testing.assert_allclose(summary["reaction_moment_Nm"],
                               -np.asarray(summary["applied_moment_Nm"]), atol=1e-5 * weight)
    with open(out / "positions.csv") as file:
        rows = list(csv.DictReader(file))
    assert [int(r["node"]) for r in rows] == list(range(247))
    positions = np.array([[float(r[k]) for k in ("x_m", "y_m", "z_m")] for r in rows])
    model = jt.read_kite_fem(V3_MODEL)
    held = [0, 72, 81, 106, 115, 127, 128, 129]
    np.testing.assert_array_equal(positions[held], model.node_position[held])
    np.testing.assert_allclose(positions[[82, 116]], model.node_position[[82, 116]], atol=1e-9)
    assert np.linalg.norm(positions - model.node_position, axis=1).max() > 0.01  # it sags
    with open(out / "lines.csv") as file:
        lines = list(csv.DictReader(file))
    assert len(lines) == 664 + 14
    assert {r["state"] for r in lines} <= {"taut", "slack"}
    assert sum(r["element"] == "bridle" for r in lines) == 46
    assert all(float(r["tension_N"]) > 0 for r in lines if r["element"] == "bridle"
               and r["state"] == "taut")
    assert sum(r["state"] == "taut" for r in lines if r["element"] == "bridle") >= 20
    assert (out / "kite_shape.png").stat().st_size > 10_000
