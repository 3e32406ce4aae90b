"""The one units table (``jaxtube.UNITS``, ``jaxtube.unit_factor``), the problems collector
(``jaxtube.Problem``, ``jaxtube.ProblemReport``) behind ``SpecError``, and the spring-joint
topology that ``Structure`` exposes once. Nothing here compiles a solve."""

import decimal

import numpy as np
import pytest

import jaxtube as jt
from jaxtube._spec import SpecError, parse_spec


def test_unit_factors_are_exact_powers_of_ten():
    assert jt.unit_factor("pressure", "bar") == 1.0e5
    assert jt.unit_factor("pressure", "kPa") == 1.0e3
    assert jt.unit_factor("pressure", "Pa") == 1.0
    assert jt.unit_factor("length", "mm") == 1.0e-3
    assert jt.unit_factor("force", "kN") == 1.0e3
    assert jt.unit_factor("mass", "g") == 1.0e-3
    assert jt.UNITS["pressure"]["bar"] == decimal.Decimal("1E+5")
    # The order is the order of the messages: the usual unit first.
    assert list(jt.UNITS["pressure"]) == ["bar", "kPa", "Pa"]
    with pytest.raises(TypeError):
        jt.UNITS["pressure"]["psi"] = decimal.Decimal("6894.757")  # read-only


def test_unit_lookup_errors_name_what_is_accepted():
    with pytest.raises(ValueError, match=r"unknown unit 'psi' for pressure; accepted: "
                                         r"bar, kPa, Pa"):
        jt.unit_factor("pressure", "psi")
    with pytest.raises(ValueError, match=r"unknown quantity 'speed'; expected one of "
                                         r"pressure, length, force, mass"):
        jt.unit_factor("speed", "m_per_s")


def test_problem_text_for_a_key_path_and_for_a_table_cell():
    assert str(jt.Problem("a.toml", "expected a positive integer, found 0",
                          key="tube[0].segments")) == (
        "a.toml: tube[0].segments: expected a positive integer, found 0")
    assert str(jt.Problem("a.toml", "TOML syntax error")) == "a.toml: TOML syntax error"
    assert str(jt.Problem("d.csv", "expected a number, found 'x'", line=12,
                          column="force_N")) == (
        "d.csv:12: column 'force_N': expected a number, found 'x'")
    assert str(jt.Problem("d.csv", "wrong number of fields", line=3)) == (
        "d.csv:3: wrong number of fields")


def test_report_gathers_every_problem_and_raises_once():
    class InputError(ValueError):
        def __init__(self, problems):
            self.records = problems
            super().__init__("\n".join(map(str, problems)))

    report = jt.ProblemReport("d.csv")
    report.raise_if_any(InputError)  # nothing found: no error
    report.add("", "expected a number, found 'x'", line=4, column="force_N")
    report.add("path.steps", "expected a positive integer, found 0")
    assert len(report) == 2
    with pytest.raises(InputError) as error:
        report.raise_if_any(InputError)
    assert [p.line for p in error.value.records] == [4, None]
    assert str(error.value).splitlines() == [
        "d.csv:4: column 'force_N': expected a number, found 'x'",
        "d.csv: path.steps: expected a positive integer, found 0"]


def test_spec_errors_are_lines_built_from_problems():
    with pytest.raises(SpecError) as error:
        parse_spec("[path]\ncontrol = 'displacement'\n", source="s.toml")
    assert all(isinstance(line, str) and line.startswith("s.toml: ")
               for line in error.value.problems)
    assert str(error.value) == "\n".join(error.value.problems)


def test_spring_joint_topology_lists_the_spring_joints_once():
    """A pinned frame with a rigidly attached strut and a clamp at the far end: tree joints
    with springs first (in tree order), then the derived clamp joint; pinned joints carry
    no spring."""
    law = jt.LinearLaw(10.0)
    beam = jt.straight_tube("beam", (0, 0, 0), (1, 0, 0), 4, 0.05, 2e4, law)
    strut = jt.straight_tube("strut", (0.5, 0, 0), (0.5, 0, -0.5), 2, 0.03, 2e4, law)
    structure, _ = jt.build_structure(
        [beam, strut], [jt.Support("beam:0", "pinned"), jt.Support("beam:end", "clamped")],
        [jt.Connection("beam:2", "strut:0", "rigid")])
    topology = structure.spring_joint_topology()
    springs = [s for s, spring in enumerate(structure.joint_spring) if spring]
    assert topology.spring_segments == tuple(springs)
    count = len(springs) + len(structure.derived_frames)
    assert topology.parent_segment.shape == topology.child_segment.shape == (count,)
    assert len(topology.node) == len(topology.law) == len(topology.kind) == count
    np.testing.assert_array_equal(topology.child_segment[:len(springs)], springs)
    np.testing.assert_array_equal(
        topology.parent_segment[:len(springs)],
        [structure.orientation_parent[s] for s in springs])
    # The pinned root carries no spring; the far clamp is a derived joint to the ground.
    assert 0 not in topology.spring_segments
    assert topology.parent_segment[-1] == -1
    assert topology.kind[-1] == 2  # JOINT_GROUND
    assert topology.node[-1] == structure.node_id("beam:end")
    # The strut's joint at the beam follows the strut's law (tube 1), half a segment.
    strut_joints = [j for j, law_tube in enumerate(topology.law) if law_tube == 1]
    assert topology.node[strut_joints[0]] == structure.node_id("beam:2")
    assert topology.kind[strut_joints[0]] == 1  # JOINT_ATTACH
