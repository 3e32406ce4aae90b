"""Spec tables [[point]], [[line]], [[pulley]], [[canopy]], [[point_mass]]: a good spec
assembles into the elements API; bad ones name the key path, what was expected and what was
found, all problems at once. Assembly only: nothing is compiled here."""

import re

import numpy as np
import pytest

from jaxtube import SpecError
from jaxtube._spec import parse_spec

HUNG = """
name = "hung beam"
[[tube]]
name = "beam"
segments = 4
pressure_bar = 0.2
radius_m = 0.05
[tube.centreline]
kind = "straight"
start_m = [0, 0, 0]
end_m = [1, 0, 0]
[tube.bending_law]
kind = "empirical_2011"

[[point]]
name = "left_hook"
position_m = [0, 0, 1]
fixed = true
[[point]]
name = "right_hook"
position_m = [1, 0, 1]
fixed = true
[[point]]
name = "te_0"
position_m = [0, 0.4, 0]
mass_kg = 0.1
[[point]]
name = "te_1"
position_m = [0.5, 0.4, 0]
[[point]]
name = "te_2"
position_m = [1, 0.4, 0]
force_N = [0, 0, -1]
[[point]]
name = "block"
position_m = [0.5, 0, 0.5]

[[line]]
nodes = ["left_hook", "beam:start"]
stiffness_N_per_m = 5000
name = "left line"
[[line]]
nodes = ["right_hook", "block"]
stiffness_N_per_m = 5000
rest_length_m = 0.70
[[pulley]]
nodes = ["beam:2", "block", "beam:end"]
stiffness_N_per_m = 4000

[[canopy]]
name = "sail"
grid = [["beam:0", "beam:2", "beam:4"], ["te_0", "te_1", "te_2"]]
stiffness_N_per_m = 2000
rest_length_factor = 0.99

[[point_mass]]
node = "beam:2"
mass_kg = 0.3

[[load]]
node = "beam:end"
force_N = [0, 0, -2]

[path]
control = "force"
"""


def test_good_spec_assembles():
    structure, params, _, meta = parse_spec(HUNG, source="hung.toml")
    topology, elements = structure.elements, params.elements
    assert structure.supports == ()  # held by lines to the fixed points
    assert len(topology.point_names) == 6 and len(topology.fixed_points) == 2
    # Two lines, then the canopy: 2 x 2 along the rows, 3 down the columns, 2 x 2 diagonals.
    assert len(topology.line_names) == 2 + 4 + 3 + 4
    assert topology.line_names[0] == "left line" and topology.line_names[1] == "line[1]"
    assert "canopy sail (0,0)-(1,1)" in topology.line_names
    assert topology.pulley_names == ("pulley[0]",)
    np.testing.assert_allclose(elements.line_rest_length[1], 0.70)
    np.testing.assert_allclose(elements.line_rest_length[0], 1.0)  # reference distance
    # Canopy rest lengths: 0.99 x the reference lengths (a row, a column, a diagonal).
    names = list(topology.line_names)
    for pair, length in ((("0,0", "0,1"), 0.5), (("0,0", "1,0"), 0.4),
                         (("0,1", "1,2"), np.hypot(0.5, 0.4))):
        k = names.index(f"canopy sail ({pair[0]})-({pair[1]})")
        assert float(elements.line_rest_length[k]) == pytest.approx(0.99 * length)
    np.testing.assert_allclose(sorted(np.asarray(elements.point_mass)), [0.1, 0.3])
    np.testing.assert_allclose(params.gravity, [0, 0, -9.81])  # something has mass
    assert meta.control == "force" and meta.control_node == structure.node_id("beam:end")


@pytest.mark.parametrize("edit, pattern", [
    (('nodes = ["left_hook", "beam:start"]', 'nodes = ["left_hok", "beam:start"]'),
     r"line\[0\]\.nodes\[0\]: node 'left_hok' does not exist: no \[\[point\]\] named "
     r"'left_hok'; did you mean 'left_hook'\?"),
    (('nodes = ["left_hook", "beam:start"]', 'nodes = ["left_hook"]'),
     r"line\[0\]\.nodes: expected two node names \[a, b\], found a list of 1 item"),
    (('nodes = ["left_hook", "beam:start"]', 'nodes = ["left_hook", "beam:9"]'),
     r"line\[0\]\.nodes\[1\]: node 'beam:9' does not exist: tube 'beam' has nodes 0\.\.4"),
    (("stiffness_N_per_m = 4000", "stiffness_N_per_m = -4000"),
     r"pulley\[0\]\.stiffness_N_per_m: expected a positive number, found -4000"),
    (('nodes = ["beam:2", "block", "beam:end"]', 'nodes = ["beam:2", "block", "beam:2"]'),
     r"pulley\[0\]\.nodes: expected 3 different nodes"),
    (('["te_0", "te_1", "te_2"]', '["te_0", "te_1"]'),
     r"canopy\[0\]\.grid: expected two or more rows of node names, every row the same length"),
    (('["te_0", "te_1", "te_2"]', '["te_0", "te_1", "beam:4"]'),
     r"canopy\[0\]\.grid: expected each node once in the grid, found \['beam:4'\]"),
    (("rest_length_factor = 0.99", "rest_lenght_factor = 0.99"),
     r"canopy\[0\]\.rest_lenght_factor: unknown key; did you mean 'rest_length_factor'\?"),
    (('name = "te_1"', 'name = "te_0"'),
     r"point\[3\]\.name: expected a unique point name, found 'te_0' twice"),
    (('name = "te_1"', 'name = "beam:7"'),
     r"point\[3\]\.name: expected a non-empty name without ':'"),
    (("position_m = [0, 0, 1]\nfixed = true", "position_m = [0, 0, 1]\nfixed = true\n"
                                              "mass_kg = 1"),
     r"point\[0\]: a fixed point takes no mass_kg or force_N"),
    (("fixed = true\n[[point]]\nname = \"right_hook\"", "fixed = 1\n[[point]]\n"
                                                       "name = \"right_hook\""),
     r"point\[0\]\.fixed: expected true or false, found 1"),
    (('node = "beam:2"\nmass_kg = 0.3', 'node = "right_hook"\nmass_kg = 0.3'),
     r"point_mass\[0\]\.node: expected a node that moves, found the fixed point 'right_hook'"),
    (("mass_kg = 0.3", "mass_kg = 0"),
     r"point_mass\[0\]\.mass_kg: expected a positive number, found 0"),
    (("mass_kg = 0.1", "mass_kg = -0.1"),
     r"point\[2\]\.mass_kg: expected a number >= 0, found -0.1"),
])
def test_bad_element_tables(edit, pattern):
    with pytest.raises(SpecError) as error:
        parse_spec(HUNG.replace(*edit), source="hung.toml")
    lines = error.value.problems
    assert any(re.search(pattern, line) for line in lines), (pattern, lines)
    assert all(line.startswith("hung.toml: ") for line in lines)


def test_problems_reported_together_and_held_frames_need_a_fixed_point():
    bad = (HUNG.replace("fixed = true", "fixed = false")
           .replace("stiffness_N_per_m = 2000", "stiffness_N_per_m = 'stiff'"))
    with pytest.raises(SpecError) as error:
        parse_spec(bad, source="hung.toml")
    lines = error.value.problems
    assert any(re.search(r"canopy\[0\]\.stiffness_N_per_m: expected a positive number, "
                         r"found the string 'stiff'", line) for line in lines), lines
    assert any(re.search(r"support: missing required key \(expected one or more \[\[support\]\] "
                         r"tables, or a \[\[point\]\] with fixed = true", line)
               for line in lines), lines
