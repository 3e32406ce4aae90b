"""The ``[kite]`` spec table, the kite generator's geometry and the 3-D figure of a kite.

Nothing here compiles a solve (the kite's physics is in ``tests/test_kite.py``)."""

import math
import re
from pathlib import Path

import numpy as np
import pytest

import jaxtube as jt
from jaxtube._plot import deformed_shape_figure
from jaxtube._spec import SpecError, load_spec, parse_spec
from jaxtube._spec import kite as _kite_spec

EXAMPLES = Path(jt.__file__).parent / "examples"

KITE = """
[kite]
tip_support = "pinned"
[kite.leading_edge]
segments = 16
pressure_bar = 0.25
span_m = 2.4
arc_height_m = 0.9
centre_radius_m = 0.08
tip_radius_m = 0.04
[kite.leading_edge.bending_law]
kind = "tension_field"
wall_modulus_N_per_m = 150e3
[[kite.strut]]
span_fraction = 0.25
chord_m = 0.7
segments = 4
root_radius_m = 0.05
tip_radius_m = 0.025
pressure_kPa = 30
[[kite.strut]]
span_fraction = 0.75
chord_m = 0.7
segments = 4
radius_m = 0.04
[[load]]
node = "le:centre"
force_N = [0, 0, -10]
[path]
control = "displacement"
node = "le:centre"
direction = [0, 0, -1]
max_displacement_mm = 50
"""


def test_kite_spec_builds_the_frame():
    structure, params, path, meta = parse_spec(KITE)
    assert structure.tube_names == ("le", "strut_1", "strut_2")
    crown = structure.node_id("le:8")
    assert path.node == crown and meta.control_node_ref == "le:centre"
    assert meta.loads[0][:2] == ("le:centre", crown)
    assert [(ref, kind) for ref, _, kind in meta.supports] == [("le:0", "pinned"),
                                                              ("le:16", "pinned")]
    # Struts share the leading-edge node they attach to (rigid connections merge nodes).
    assert structure.node_id("strut_1:0") == structure.node_id("le:4")
    assert structure.node_id("strut_2:0") == structure.node_id("le:12")
    np.testing.assert_allclose(params.pressure, [2.5e4, 3e4, 2.5e4])  # strut_2 shares
    position = np.asarray(params.node_position)
    np.testing.assert_allclose(position[crown], [0.0, 0.0, 0.9], atol=1e-12)
    np.testing.assert_allclose(position[structure.node_id("le:0")], [0, -1.2, 0], atol=1e-12)
    np.testing.assert_allclose(position[structure.node_id("strut_1:end")]
                               - position[structure.node_id("le:4")], [0.7, 0, 0], atol=1e-12)
    radius = np.asarray(params.node_radius)
    assert radius[crown] == pytest.approx(0.08)
    assert radius[structure.node_id("le:0")] == pytest.approx(0.04)
    assert radius[structure.node_id("strut_1:end")] == pytest.approx(0.025)


def test_bundled_kite_example_and_old_examples_load():
    structure, params, path, meta = load_spec(EXAMPLES / "tube_kite.toml")
    assert structure.tube_names == ("le", "strut_1", "strut_2", "strut_3", "strut_4")
    assert meta.control_node_ref == "le:centre" and path.node == structure.node_id("le:12")
    assert meta.steps == 28
    np.testing.assert_allclose(params.gravity, [0, 0, -9.81])  # tubes have mass
    for name in ("cantilever.toml", "arch.toml"):  # version-1 specs stay valid
        load_spec(EXAMPLES / name)


def test_kite_spec_errors_are_reported_together():
    bad = (KITE.replace("segments = 16", "segments = 15")
           .replace("span_fraction = 0.25", "span_fraction = 1.2\nchrod_m = 1")
           .replace("tip_radius_m = 0.04\n", "")
           .replace('tip_support = "pinned"', 'tip_support = "glued"'))
    with pytest.raises(SpecError) as error:
        parse_spec(bad + "\n[[point_mass]]\nnode = 'le:centre'\nmass_kg = -1\n",
                   source="kite.toml")
    lines = error.value.problems
    expected = [
        r"kite\.tip_support: expected one of 'clamped', 'pinned', found 'glued'",
        r"kite\.leading_edge\.segments: expected an even number .* found 15",
        r"kite\.leading_edge\.tip_radius_m: missing required key",
        r"kite\.strut\[0\]\.chrod_m: unknown key; did you mean 'chord_m'\?",
        r"kite\.strut\[0\]\.span_fraction: expected a fraction .* found 1\.2",
        r"point_mass\[0\]\.mass_kg: expected a positive number, found -1",
    ]
    for pattern in expected:
        assert any(re.search(pattern, line) for line in lines), (pattern, lines)
    assert all(line.startswith("kite.toml: ") for line in lines)
    # The kite's node names are not reported again once the kite itself is bad.
    assert not any(re.match(r"kite\.toml: (load|path)", line) for line in lines), lines


@pytest.mark.parametrize("edit, pattern", [
    (("span_m = 2.4", "points_m = [[0, -1, 0], [0, 0, 1], [0, 1, 0]]"),
     r"kite\.leading_edge\.arc_height_m: cannot be combined with points_m"),
    (("span_fraction = 0.75", "span_fraction = 0.27"),
     r"kite: cannot build the kite: two struts attach at the same leading-edge node"),
    (('[[load]]\nnode = "le:centre"', '[[load]]\nnode = "strut_3:end"'),
     r"load\[0\]\.node: node 'strut_3:end' does not exist: no tube named 'strut_3'"),
    (("[kite]", "[[tube]]\nname = 'le'\n[kite]"), r"kite: the kite's tube 'le' clashes"),
])
def test_kite_spec_single_errors(edit, pattern):
    with pytest.raises(SpecError) as error:
        parse_spec(KITE.replace(*edit))
    assert any(re.search(pattern, line) for line in error.value.problems), \
        error.value.problems


def test_kite_spec_keys_are_documented():
    doc = _kite_spec.__doc__
    keys = set(_kite_spec._LE_KEYS) | set(_kite_spec._STRUT_KEYS) | {
        "tip_support", "leading_edge", "strut"}
    assert sorted(k for k in keys if not re.search(rf"\b{k}\b", doc)) == []
    spec_doc = jt._spec.__doc__
    for table in ("[kite]", "[[canopy]]", "[[line]]", "[[point_mass]]"):
        assert table in spec_doc


def test_sampled_centreline_and_api_errors():
    law = jt.LinearLaw(100.0)
    points = [(0.0, -1.0, 0.0), (0.0, -0.5, 0.6), (0.0, 0.5, 0.6), (0.0, 1.0, 0.0)]
    kite = jt.TubeKite(segments=8, radius=0.05, pressure=2e4, bending_law=law,
                       centreline=tuple(points))
    structure, params = kite.build()
    position = np.asarray(params.node_position)
    np.testing.assert_allclose(position[structure.node_id(kite.node("le:left_tip"))],
                               points[0], atol=1e-12)
    np.testing.assert_allclose(position[structure.node_id(kite.node("le:right_tip"))],
                               points[-1], atol=1e-12)
    np.testing.assert_allclose(position[structure.node_id(kite.node("le:centre"))],
                               [0.0, 0.0, 0.6], atol=1e-12)
    with pytest.raises(ValueError, match="even number of segments"):
        jt.TubeKite(segments=7, radius=0.05, pressure=2e4, bending_law=law, span=2.0,
                    arc_height=0.5)
    with pytest.raises(ValueError, match="either span and arc_height"):
        jt.TubeKite(segments=8, radius=0.05, pressure=2e4, bending_law=law, span=2.0,
                    arc_height=0.5, centreline=tuple(points))
    with pytest.raises(ValueError, match="falls on a wing tip"):
        jt.TubeKite(segments=8, radius=0.05, pressure=2e4, bending_law=law, span=2.0,
                    arc_height=0.5, struts=(jt.Strut(0.02, 0.5, 0.03, 2),))


@pytest.mark.parametrize("span, height", [(2.4, 0.9), (2.0, 1.5)])
def test_arc_passes_through_tips_and_crown(span, height):
    """The circle from ``arc_through_tips`` passes through both tips and the crown, also
    for an arc of more than a half circle; mirrored strut fractions give mirrored nodes."""
    radius, half_angle = jt.arc_through_tips(span, height)
    centre = height - radius
    assert math.hypot(span / 2, centre) == pytest.approx(radius, rel=1e-12)
    assert (half_angle > math.pi / 2) == (height > span / 2)
    struts = tuple(jt.Strut(f, 0.5, 0.03, 2) for f in (0.125, 0.3, 0.7, 0.875))
    kite = jt.TubeKite(segments=20, radius=0.05, pressure=2e4, bending_law=jt.LinearLaw(1.0),
                       span=span, arc_height=height, struts=struts)
    nodes = np.asarray(kite.leading_edge().nodes)
    np.testing.assert_allclose(nodes[[0, 10, 20]], [[0, -span / 2, 0], [0, 0, height],
                                                    [0, span / 2, 0]], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(nodes - [0, 0, centre], axis=1), radius)
    attached = [kite.strut_attachment(k) for k in range(4)]
    assert attached == [2, 6, 14, 18]  # 2.5 -> 2 and 17.5 -> 18: ties away from the centre


def test_kite_figure_draws_supports_loads_and_regimes(tmp_path):
    structure, params, _, meta = load_spec(EXAMPLES / "tube_kite.toml")
    reference = np.asarray(params.node_position)
    positions = np.stack([reference, reference + [0.0, 0.0, -0.05]])
    joint_node = np.arange(structure.node_count)
    regime = np.zeros((2, structure.node_count), dtype=int)
    regime[1, :3] = [2, 1, 1]
    distributed = np.broadcast_to(np.asarray(params.mass_per_length)[:, None]
                                  * np.asarray(params.gravity), (2, 5, 3))
    fig = deformed_shape_figure(
        structure, reference, positions, [True, True], joint_node=joint_node,
        joint_regime=regime, control=(meta.control_node, meta.control_direction, [5.0, 9.0]),
        distributed=distributed, title="kite")
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    for label in ("undeformed", "deformed (step 2)", "joint unwrinkled", "joint wrinkled",
                  "joint collapsed", "clamped support", "actuator force"):
        assert label in labels
    assert "line load / self-weight (up to 2.45 N/m)" in labels  # 0.25 kg/m x 9.81 m/s^2
    fig.savefig(tmp_path / "kite.png")


def test_strut_is_a_rigid_attachment_with_half_tributary():
    """At a strut's root node the leading edge keeps its bending joint (tributary: one
    leading-edge segment) and the strut gets an attachment joint with its own law and half
    of its first segment (docs/physics.md, section 1.2); every node of both tubes is a joint."""
    from jaxtube._mechanics import initial_state, reference_geometry, spring_joints

    kite = jt.TubeKite(segments=8, radius=0.05, pressure=2e4, bending_law=jt.LinearLaw(10.0),
                       span=2.0, arc_height=0.6, struts=(jt.Strut(0.25, 0.6, 0.03, 3),))
    structure, params = kite.build()
    geometry = reference_geometry(structure, params)
    joints = spring_joints(structure, geometry, initial_state(structure, params))
    root = structure.node_id(kite.node("strut_1:root"))
    assert root == structure.node_id("le:2")
    at_root = {structure.tube_names[t]: float(geometry.joint_tributary[j])
               for j, (n, t) in enumerate(zip(joints.node, joints.law_tube)) if n == root}
    le = np.asarray(params.node_position)[list(structure.tube_node_ids[0])]
    le_segment = float(np.linalg.norm(le[2] - le[1]))
    assert at_root == pytest.approx({"le": le_segment, "strut_1": 0.1})
    # 9 leading-edge joints (both clamps included), 3 strut joints (root, two interior).
    assert sorted(structure.tube_names[t] for t in joints.law_tube).count("le") == 9
    assert sorted(structure.tube_names[t] for t in joints.law_tube).count("strut_1") == 3
