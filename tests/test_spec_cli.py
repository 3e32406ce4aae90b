"""Spec loading and validation, the ``jaxtube simulate`` command and its outputs.

One real simulation (the bundled cantilever, few steps) is shared by the CLI tests; the
rest checks specs, reports and writing without compiling a solver.
"""

import csv
import dataclasses
import json
import re
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

import jaxtube._spec as spec_module
from fitting._cli import main
from fitting._cli.simulate import (
    CSV_COLUMNS,
    OUTPUT_FILES,
    _failure_lines,
    _write_csv,
    write_outputs,
)
from jaxtube import DisplacementControl, ForceControl
from jaxtube._plot import deformed_shape_figure, force_deflection_figure
from jaxtube._spec import SpecError, load_spec, parse_spec
from jaxtube._spec import laws as spec_laws
from jaxtube._spec import load as spec_load
from jaxtube._spec import tables as spec_tables
from jaxtube._spec import tubes as spec_tubes

EXAMPLES = resources.files("jaxtube") / "examples"
CANTILEVER = EXAMPLES / "cantilever.toml"
CANTILEVER_TEXT = CANTILEVER.read_text()
SIMULATED_STEPS = 10


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """Run ``jaxtube simulate`` on the bundled cantilever once (10 steps to 150 mm)."""
    out = tmp_path_factory.mktemp("run") / "cantilever_out"
    with resources.as_file(CANTILEVER) as spec_path:
        code = main(["simulate", str(spec_path), "--out", str(out), "--steps",
                     str(SIMULATED_STEPS), "--quiet"])
    with open(out / "path.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    return code, out, rows


def test_bundled_example_simulates(simulated):
    code, out, rows = simulated
    assert code == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(OUTPUT_FILES)
    assert all((out / name).stat().st_size > 0 for name in OUTPUT_FILES)
    assert list(rows[0].keys()) == list(CSV_COLUMNS)
    assert [int(r["step"]) for r in rows] == list(range(1, SIMULATED_STEPS + 1))
    assert all(r["converged"] == "1" and r["status"] == "converged" for r in rows)
    displacement = np.array([float(r["control_displacement_mm"]) for r in rows])
    np.testing.assert_allclose(displacement, 15.0 * np.arange(1, SIMULATED_STEPS + 1),
                               rtol=1e-9)
    force = np.array([float(r["control_force_N"]) for r in rows])
    assert np.all(force > 0) and np.all(np.diff(force[:4]) > 0)
    # The tip is pushed straight down along -z: dz = -displacement.
    dz = np.array([float(r["control_node_dz_mm"]) for r in rows])
    np.testing.assert_allclose(dz, -displacement, rtol=1e-9)


def test_small_deflection_matches_beam_theory(simulated):
    """First step (15 mm, below wrinkling): F = 3 EI delta / L^3 with the law's EI."""
    _, _, rows = simulated
    _, params, _, _ = load_spec(CANTILEVER)
    stiffness = float(params.bending_laws[0].initial_stiffness(params.pressure[0], 0.075))
    expected = 3.0 * stiffness * 0.015 / 1.0**3
    assert float(rows[0]["control_force_N"]) == pytest.approx(expected, rel=0.02)
    assert rows[0]["joints_wrinkled"] == "0"
    # Far along the path the root has wrinkled and the force is below M_c / L = pi p r^3.
    assert int(rows[-1]["joints_wrinkled"]) + int(rows[-1]["joints_collapsed"]) > 0
    assert float(rows[-1]["control_force_N"]) < np.pi * 0.2e5 * 0.075**3


def test_summary_json(simulated):
    _, out, rows = simulated
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == SIMULATED_STEPS
    assert summary["converged_steps"] == SIMULATED_STEPS
    assert summary["failed_steps"] == []
    assert summary["spec"].endswith("cantilever.toml")
    assert summary["control_node"] == "beam:end"
    assert summary["final_displacement_mm"] == pytest.approx(150.0)
    assert summary["final_force_N"] == pytest.approx(float(rows[-1]["control_force_N"]))
    assert summary["wall_time_s"]["total_s"] > 0


def test_existing_output_directory_keeps_other_files(tmp_path):
    """Writing into an existing DIR replaces only the files jaxtube writes."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    (out / "path.csv").write_text("old")
    table = _table(converged=[True, True])
    write_outputs(out, table, {}, _summary(), 0.0)
    assert (out / "notes.txt").read_text() == "mine"
    assert (out / "path.csv").read_text().startswith("step,")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no staging left behind


# ------------------------------------------------------------------------------------------
# Bad specs
# ------------------------------------------------------------------------------------------


def _bad(tmp_path, old, new, count=1):
    assert CANTILEVER_TEXT.count(old) == count, old
    path = tmp_path / "cantilever.toml"
    path.write_text(CANTILEVER_TEXT.replace(old, new))
    with pytest.raises(SpecError) as info:
        load_spec(path)
    return str(info.value)


BAD_SPECS = {
    "unknown key": ("segments = 20", "segments = 20\nsegmnts = 3",
                    "tube[0].segmnts", ["unknown key", "did you mean 'segments'"]),
    "negative pressure": ("\npressure_bar = 0.2", "\npressure_bar = -0.2",
                          "tube[0].pressure_bar", ["expected a positive number", "-0.2"]),
    "zero segments": ("segments = 20", "segments = 0", "tube[0].segments",
                      ["expected a positive integer", "found 0"]),
    "non-integer segments": ("segments = 20", "segments = 20.5", "tube[0].segments",
                             ["expected a positive integer", "20.5"]),
    "string segments": ("segments = 20", 'segments = "20"', "tube[0].segments",
                        ["expected a positive integer", "the string '20'"]),
    "non-increasing pivots": ("0.6, 1.8, 3.9", "0.6, 0.5, 3.9",
                              "tube[0].bending_law.curvature_per_m",
                              ["strictly increasing", "0.5"]),
    "wrong pivot count": ("25.7, 26.0, 26.2]", "25.7, 26.0]", "tube[0].bending_law.moment_Nm",
                          ["expected 9 values", "found 8"]),
    "load on missing node": ("[path]", '[[load]]\nnode = "beam:21"\nforce_N = [0, 0, -1]\n\n'
                             "[path]", "load[0].node",
                             ["'beam:21' does not exist", "nodes 0..20"]),
    "missing tube": ('node = "beam:end"', 'node = "bem:end"', "path.node",
                     ["no tube named 'bem'", "did you mean 'beam'", "tubes: 'beam'"]),
    "unknown support kind": ('kind = "clamped"', 'kind = "fixed"', "support[0].kind",
                             ["expected one of 'clamped', 'pinned'", "'fixed'"]),
    "unknown law kind": ('kind = "linear"', 'kind = "elastic"', "tube[0].torsion_law.kind",
                         ["expected one of 'spline'", "'elastic'"]),
    "vector length": ("direction = [0.0, 0.0, -1.0]", "direction = [0.0, -1.0]",
                      "path.direction", ["expected a list of 3 numbers", "2 items"]),
    "zero direction": ("direction = [0.0, 0.0, -1.0]", "direction = [0, 0, 0]",
                       "path.direction", ["non-zero"]),
    "missing required": ("max_displacement_mm = 150.0", "", "path.max_displacement_mm",
                         ["missing required key", "positive displacement"]),
    "two pressures": ("\npressure_bar = 0.2", "\npressure_bar = 0.2\npressure_kPa = 20",
                      "tube[0].pressure_kPa", ["exactly one of pressure_bar"]),
    "bad taper": ("\nradius_m = 0.075", "\nradius_m = [[0, 0.08], [0.6, 0.07], [0.4, 0.06]]",
                  "tube[0].radius_m", ["strictly increasing", "[0.0, 0.6, 0.4]"]),
    "unknown table": ("[path]", "[solver]\nmax_steps = 5\n\n[path]", "solver",
                      ["unknown top-level key or table", "allowed here:"]),
    "path at support": ('node = "beam:end"', 'node = "beam:0"', "path.node",
                        ["free to move", "support[0]"]),
    "format too new": ("format_version = 1", "format_version = 7", "format_version",
                       ["format version this jaxtube reads", "found 7"]),
    "force control keys": ('control = "displacement"', 'control = "force"',
                           "path.max_displacement_mm",
                           ["unknown key", "max_load_factor"]),
}


@pytest.mark.parametrize("case", list(BAD_SPECS), ids=list(BAD_SPECS))
def test_bad_spec_message(tmp_path, case):
    old, new, key_path, expectations = BAD_SPECS[case]
    message = _bad(tmp_path, old, new)
    line = next((m for m in message.splitlines() if f": {key_path}:" in m), None)
    assert line is not None, message
    assert line.startswith(f"{tmp_path / 'cantilever.toml'}: {key_path}: ")
    for expected in expectations:
        assert expected in line, line


def test_toml_syntax_error_gives_line(tmp_path):
    message = _bad(tmp_path, "segments = 20", "segments = = 20")
    assert "cantilever.toml: TOML syntax error" in message
    assert "line 14" in message


def test_all_problems_reported_together(tmp_path):
    text = (CANTILEVER_TEXT.replace("segments = 20", "segments = -3")
            .replace('kind = "clamped"', 'kind = "clamp"')
            .replace("max_displacement_mm = 150.0", "max_displacement_mm = 0"))
    with pytest.raises(SpecError) as info:
        parse_spec(text, source="many.toml")
    lines = str(info.value).splitlines()
    assert len(lines) == len(info.value.problems) == 3
    assert all(line.startswith("many.toml: ") for line in lines)
    assert [line.split(": ")[1] for line in lines] == [
        "tube[0].segments", "support[0].kind", "path.max_displacement_mm"]


def test_law_value_error_is_reraised_with_key_path(monkeypatch):
    def refuse(*args, **kwargs):
        raise ValueError("Pivot curvatures must be positive and strictly increasing")

    monkeypatch.setattr(spec_laws.SplineLaw, "from_pivots", refuse)
    with pytest.raises(SpecError) as info:
        parse_spec(CANTILEVER_TEXT, source="cantilever.toml")
    assert str(info.value).startswith(
        "cantilever.toml: tube[0].bending_law: invalid spline law: Pivot curvatures")


def test_connection_nodes_must_coincide():
    text = CANTILEVER_TEXT + """
[[tube]]
name = "strut"
segments = 2
pressure_bar = 0.2
radius_m = 0.05
[tube.centreline]
kind = "straight"
start_m = [0.5, 0.0, 0.1]
end_m = [0.5, 0.0, 0.5]
[tube.bending_law]
kind = "linear"
stiffness_Nm2 = 50.0

[[connection]]
nodes = ["beam:10", "strut:start"]
"""
    with pytest.raises(SpecError) as info:
        parse_spec(text, source="frame.toml")
    assert str(info.value).startswith("frame.toml: connection[0].nodes: expected coincident "
                                      "nodes, found them 0.1 m apart")
    loaded = parse_spec(text.replace("[0.5, 0.0, 0.1]", "[0.5, 0.0, 0.0]"), source="frame.toml")
    assert loaded.structure.node_count == 21 + 3 - 1


def test_spec_error_is_a_value_error():
    assert issubclass(SpecError, ValueError)
    with pytest.raises(ValueError, match="cannot read the spec file"):
        load_spec("/nonexistent/spec.toml")


# ------------------------------------------------------------------------------------------
# Good specs
# ------------------------------------------------------------------------------------------


def test_bundled_examples_load():
    structure, params, path, meta = load_spec(CANTILEVER)
    assert isinstance(path, DisplacementControl)
    assert path.node == structure.node_id("beam:end") == 20
    np.testing.assert_allclose(path.displacements[-1], 0.150)
    np.testing.assert_allclose(path.displacements[0], 0.150 / 30)
    np.testing.assert_allclose(params.pressure, [0.2e5])
    np.testing.assert_allclose(params.gravity, 0.0)  # massless: gravity off by default
    assert meta.steps == 30 and meta.control_node_ref == "beam:end"

    structure, params, path, meta = load_spec(EXAMPLES / "arch.toml")
    assert [kind for _, _, kind in meta.supports] == ["clamped", "clamped"]
    assert path.node == 12
    radius = np.asarray(params.node_radius)
    assert radius[12] == pytest.approx(0.09) and radius[0] == pytest.approx(0.05)
    position = np.asarray(params.node_position)
    assert position[12] == pytest.approx([0.0, 0.0, 1.2], abs=1e-12)  # crown of the arc


def test_force_control_defaults_and_units():
    text = (CANTILEVER_TEXT.replace("max_displacement_mm = 150.0", "max_load_factor = 2.0")
            .replace('control = "displacement"\nnode = "beam:end"\n'
                     'direction = [0.0, 0.0, -1.0]', 'control = "force"')
            .replace("pressure_bar = 0.2\nradius_m", "pressure_kPa = 20\nradius_m")
            .replace("[path]", '[[load]]\nnode = "beam:-1"\nforce_N = [0, 0, -30]\n\n'
                     '[[load]]\nnode = "beam:end"\nforce_N = [0, 0, -10]\n'
                     'torque_Nm = [0, 1, 0]\n\n[path]'))
    structure, params, path, meta = parse_spec(text, steps=4)
    assert isinstance(path, ForceControl)
    np.testing.assert_allclose(path.load_factors, [0.5, 1.0, 1.5, 2.0])
    assert meta.control_node == 20 and meta.control_node_ref == "beam:-1"
    np.testing.assert_allclose(meta.control_direction, [0, 0, -1])
    np.testing.assert_allclose(params.node_force[20], [0, 0, -40])  # loads on a node add
    np.testing.assert_allclose(params.node_torque[20], [0, 1, 0])
    np.testing.assert_allclose(params.pressure, [2e4])


def test_mass_turns_gravity_on_and_polyline_arc_taper():
    text = """
[[tube]]
name = "bent"
segments = 4
pressure_Pa = 25000
radius_m = [[0.0, 0.05], [1.0, 0.08]]
mass_per_length_kg_per_m = 0.2
[tube.centreline]
kind = "polyline"
points_m = [[0, 0, 0], [1, 0, 0], [1, 1, 0]]
[tube.bending_law]
kind = "spline"
from_tension_field_wall_modulus_N_per_m = 150e3
[tube.torsion_law]
kind = "empirical_2011"

[[tube]]
name = "hoop"
segments = 6
pressure_bar = 0.25
radius_m = 0.05
[tube.centreline]
kind = "arc"
centre_m = [1, 1, 1]
arc_radius_m = 1.0
start_deg = -90
end_deg = 0
normal = [1, 0, 0]
reference = [0, 1, 0]
[tube.bending_law]
kind = "tension_field"
wall_modulus_N_per_m = 150e3

[[support]]
node = "bent:start"
[[connection]]
nodes = ["bent:end", "hoop:start"]
kind = "pinned"

[path]
control = "displacement"
node = "hoop:end"
direction = [0, 1, 0]
max_displacement_mm = 10
"""
    structure, params, path, meta = parse_spec(text)
    np.testing.assert_allclose(meta.gravity, [0, 0, -9.81])
    assert meta.steps == spec_module.DEFAULT_STEPS
    position = np.asarray(params.node_position)
    np.testing.assert_allclose(position[structure.node_id("bent:2")], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(position[structure.node_id("hoop:end")], [1, 2, 1], atol=1e-12)
    np.testing.assert_allclose(params.node_radius[structure.node_id("bent:0")], 0.05)
    assert type(params.torsion_laws[0]).__name__ == "EmpiricalTorsionLaw2011"
    assert params.torsion_laws[1] is params.bending_laws[1]  # default torsion = bending law


def test_spec_format_documents_every_key():
    doc = (Path(__file__).resolve().parents[1] / "docs" / "spec-format.md").read_text()
    keys = set(spec_load.TABLE_READERS) | set(spec_tubes.TUBE_KEYS)
    keys |= set(spec_laws.SPLINE_PIVOT_KEYS) | set(spec_laws.SPLINE_COMMON_KEYS)
    keys |= {spec_laws.SPLINE_TENSION_FIELD_KEY}
    keys |= {k for ks in spec_tables.PATH_KEYS.values() for k in ks}
    keys |= {"wall_modulus_N_per_m", "stiffness_Nm2", "start_m", "end_m", "centre_m",
             "arc_radius_m", "start_deg", "end_deg", "normal", "reference", "points_m",
             "force_N", "torque_Nm", "acceleration_m_per_s2", "nodes", "kind"}
    missing = sorted(k for k in keys if not re.search(rf"\b{k}\b", doc))
    assert missing == []


# ------------------------------------------------------------------------------------------
# CLI behaviour without compiling
# ------------------------------------------------------------------------------------------


def test_spec_error_leaves_no_output(tmp_path, capsys):
    bad = tmp_path / "cantilever.toml"
    bad.write_text(CANTILEVER_TEXT.replace("segments = 20", "segments = 0"))
    out = tmp_path / "out"
    assert main(["simulate", str(bad), "--out", str(out)]) == 2
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cantilever.toml"]
    err = capsys.readouterr().err
    assert "cantilever.toml: tube[0].segments: expected a positive integer, found 0" in err


def test_out_is_a_file(tmp_path, capsys):
    out = tmp_path / "out"
    out.write_text("x")
    with resources.as_file(CANTILEVER) as spec_path:
        assert main(["simulate", str(spec_path), "--out", str(out)]) == 2
    assert "not a directory" in capsys.readouterr().err


def test_parser_usage(capsys):
    assert main([]) == 2
    with pytest.raises(SystemExit) as info:
        main(["simulate", "x.toml", "--out", "o", "--steps", "0"])
    assert info.value.code == 2
    assert "expected a positive integer" in capsys.readouterr().err


class _BrokenFigure:
    def savefig(self, path, **kwargs):
        Path(path).write_text("half")
        raise OSError("disk full")


def test_failed_write_leaves_directory_untouched(tmp_path):
    out = tmp_path / "new_out"
    with pytest.raises(OSError, match="disk full"):
        write_outputs(out, _table(), {"force_deflection.png": _BrokenFigure()}, _summary(), 0.0)
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # neither DIR nor staging

    out.mkdir()
    (out / "path.csv").write_text("previous run")
    with pytest.raises(OSError):
        write_outputs(out, _table(), {"force_deflection.png": _BrokenFigure()}, _summary(), 0.0)
    assert (out / "path.csv").read_text() == "previous run"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["new_out"]


def _table(converged=(True, True, False, False, True, False)):
    converged = np.asarray(converged, dtype=bool)
    k = converged.size
    status = np.where(converged, "converged", "line search failed (no decrease of the merit "
                      "function)")
    status[-1] = "converged" if converged[-1] else "non-finite energy, gradient or Hessian"
    return {
        "step": np.arange(1, k + 1), "load_factor": np.ones(k),
        "control_displacement_mm": np.arange(1.0, k + 1),
        "control_force_N": np.where(converged, np.arange(1.0, k + 1), np.nan),
        "control_node_dx_mm": np.zeros(k), "control_node_dy_mm": np.zeros(k),
        "control_node_dz_mm": -np.arange(1.0, k + 1), "max_moment_Nm": np.ones(k),
        "max_bending_moment_Nm": np.ones(k), "joints_wrinkled": np.zeros(k, int),
        "joints_collapsed": np.zeros(k, int), "worst_regime": np.arange(k) % 3,
        "converged": converged, "iterations": np.full(k, 7), "residual": np.full(k, 1e-3),
        "status": status,
    }


def _summary():
    return {"wall_time_s": {"compile_s": 1.0, "solve_s": 0.1}}


def test_failed_steps_reported_in_words_and_marked(tmp_path):
    table = _table()
    lines = _failure_lines(table)
    assert lines == [
        "steps 3-4 of 6 did not converge: line search failed (no decrease of the merit "
        "function) (largest KKT residual 0.001)",
        "step 6 of 6 did not converge: non-finite energy, gradient or Hessian "
        "(largest KKT residual 0.001)",
    ]
    _write_csv(tmp_path / "path.csv", table)
    with open(tmp_path / "path.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    assert [r["converged"] for r in rows] == ["1", "1", "0", "0", "1", "0"]
    assert rows[2]["control_force_N"] == "nan"
    assert rows[2]["status"].startswith("line search failed")


def test_figures_with_failed_steps(tmp_path):
    table = _table()
    fig = force_deflection_figure(table["control_displacement_mm"], table["control_force_N"],
                                  table["worst_regime"], table["converged"])
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert "did not converge (3)" in labels
    fig.savefig(tmp_path / "fd.png")

    structure, params, _, _ = load_spec(CANTILEVER)
    reference = np.asarray(params.node_position)
    positions = np.stack([reference, reference + np.nan])
    fig = deformed_shape_figure(structure, reference, positions, [False, False])
    assert "no step converged" in fig.axes[0].get_title()
    fig.savefig(tmp_path / "shape.png")


def test_failed_steps_end_to_end(tmp_path, monkeypatch, capsys):
    """The whole command with a stand-in solver whose steps 3-4 fail: exit code 1, failures
    in words on stderr, outputs still written with those steps marked."""
    import jax.numpy as jnp

    import jaxtube as cli_module
    from jaxtube import Solution

    def fake_solve_path(structure, params, path):
        values = path.displacements  # [K] m
        count = values.shape[0]
        joints = structure.segment_count
        shape = params.node_position[:, 0]  # x: 0 at the root, 1 m at the tip
        position = params.node_position[None] + (values[:, None, None] * shape[None, :, None]
                                                 * path.direction[None, None, :])
        failed = (jnp.arange(count) == 2) | (jnp.arange(count) == 3)
        zeros3 = jnp.zeros((count, joints, 3))
        known = dict(
            state={}, multipliers=jnp.zeros((count, 4)), converged=~failed,
            iterations=jnp.where(failed, 60, 3), result=jnp.where(failed, 1, 0),
            residual=jnp.where(failed, 1e-2, 1e-13), node_position=position,
            joint_rotation=zeros3, joint_curvature=zeros3,
            joint_moment=zeros3 + values[:, None, None], joint_moment_world=zeros3,
            joint_regime=jnp.zeros((count, joints), dtype=jnp.int32),
            reaction_force=jnp.zeros((count, 1, 3)), control_force=600.0 * values,
            control_displacement=values, load_factor=jnp.ones(count))
        # Fields this test does not know about (added later) get zeros.
        return Solution(**{f.name: known.get(f.name, jnp.zeros((count, 1, 3)))
                           for f in dataclasses.fields(Solution)})

    monkeypatch.setattr(cli_module, "solve_path", fake_solve_path)
    out = tmp_path / "out"
    with resources.as_file(CANTILEVER) as spec_path:
        code = main(["simulate", str(spec_path), "--out", str(out), "--steps", "6"])
    assert code == 1
    captured = capsys.readouterr()
    assert ("steps 3-4 of 6 did not converge: did not converge within the maximum number of "
            "Newton steps (largest KKT residual 0.01)") in captured.err
    assert "warning: 2 of 6 steps did not converge" in captured.err
    assert "converged: 4 of 6 steps" in captured.out
    with open(out / "path.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    assert [r["converged"] for r in rows] == ["1", "1", "0", "0", "1", "1"]
    summary = json.loads((out / "summary.json").read_text())
    assert [f["step"] for f in summary["failed_steps"]] == [3, 4]
    assert summary["converged_steps"] == 4
    assert summary["final_displacement_mm"] == pytest.approx(150.0)
