"""Shapes against markers: registration, its gradient, the V3 null-model scores, bad files.

The synthetic kite is an anhedral leading-edge arc with four tapered struts of unequal
length (no symmetry a proper rotation could exploit); markers are drawn on its tube
surfaces with 2 mm noise, moved by a known rigid motion, and registered back.
"""

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import fitting
from fitting._cli.score_shape import add_score_shape

REPO = Path(__file__).resolve().parents[1]
NOISE_M = 0.002
STRUTS = 4


def synthetic_kite():
    """Nodes, tube segments (group, node_1, node_2, r_1, r_2) and strut roots."""
    angles = np.linspace(-1.1, 1.1, 13)
    leading_edge = np.stack([0.3 * np.cos(angles), 2.0 * np.sin(angles),
                             -1.2 * np.cos(angles)], 1)
    nodes = [*leading_edge]
    segments = [("LE", k, k + 1, 0.10 - 0.02 * abs(angles[k]), 0.10 - 0.02 * abs(angles[k + 1]))
                for k in range(12)]
    for j, root in enumerate((2, 5, 8, 10)):
        chord = 0.6 + 0.25 * j
        first = len(nodes)
        for s in range(1, 5):
            nodes.append(leading_edge[root] + np.array([chord * s / 4, 0.0, 0.08 * s / 4]))
        chain = [root, *range(first, first + 4)]
        segments += [(f"strut{j}", a, b, 0.07 * (1 - 0.1 * i), 0.07 * (1 - 0.1 * (i + 1)))
                     for i, (a, b) in enumerate(zip(chain[:-1], chain[1:]))]
    return np.asarray(nodes), segments


def surface_markers(surfaces, rng, per_group=6):
    """Points on each group's tube surface (+ noise) in the model frame, with group names."""
    positions = np.asarray(surfaces.node_positions)
    nodes, group_of = np.asarray(surfaces.segment_nodes), np.asarray(surfaces.segment_group)
    r0, r1 = np.asarray(surfaces.radius_start), np.asarray(surfaces.radius_end)
    points, groups = [], []
    for g, name in enumerate(surfaces.group_names):
        members = np.flatnonzero(group_of == g)
        for _ in range(per_group if name != "LE" else 3 * per_group):
            s = rng.choice(members)
            t = rng.uniform(0.1, 0.9)
            a, b = positions[nodes[s]]
            axis = (b - a) / np.linalg.norm(b - a)
            normal = np.cross(axis, rng.normal(size=3))
            normal /= np.linalg.norm(normal)
            radius = r0[s] + t * (r1[s] - r0[s])
            points.append(a + t * (b - a) + radius * normal + rng.normal(scale=NOISE_M, size=3))
            groups.append(name)
    return np.asarray(points), groups


@pytest.fixture(scope="module")
def kite():
    nodes, segments = synthetic_kite()
    surfaces = fitting.TubeSurfaces.from_segments(nodes, segments)
    rng = np.random.default_rng(7)
    model_frame, groups = surface_markers(surfaces, rng)
    rotation = Rotation.from_rotvec([1.9, -0.7, 2.4])
    translation = np.array([0.4, -1.3, 6.0])
    measured = rotation.apply(model_frame) + translation
    return surfaces, model_frame, groups, measured


def reversed_names(groups):
    return [f"strut{STRUTS - 1 - int(g[5:])}" if g.startswith("strut") else g for g in groups]


@pytest.mark.parametrize("reverse", [False, True], ids=["as numbered", "reversed"])
def test_registration_recovers_a_rigid_motion_in_both_spanwise_orders(kite, reverse):
    surfaces, model_frame, groups, measured = kite
    names = reversed_names(groups) if reverse else groups
    markers = fitting.MarkerSet.from_arrays(names, measured)
    found = fitting.register(surfaces, markers)
    assert found.converged
    assert found.registration.spanwise_groups == tuple(f"strut{j}" for j in range(STRUTS))
    assert found.registration.reversed_order is reverse
    back = np.asarray(found.registration.apply(markers.position))
    # Each marker back where it was drawn, to the noise (3-D noise of 2 mm per axis).
    assert np.sqrt(np.mean(np.sum((back - model_frame) ** 2, 1))) < 2.5 * NOISE_M
    # The RMS is the noise's normal component, and the wrong order is far worse.
    assert 0.5 * NOISE_M < found.rms_m < 1.5 * NOISE_M
    assert found.rms_by_order[not reverse] > 10 * found.rms_m


def test_marker_rms_gradient_matches_finite_differences_with_and_without_re_registration(kite):
    surfaces, _, groups, measured = kite
    markers = fitting.MarkerSet.from_arrays(groups, measured)
    found = fitting.register(surfaces, markers)
    positions = np.asarray(surfaces.node_positions)
    direction = np.random.default_rng(3).normal(size=positions.shape)

    def rms_at(x, registration):
        return fitting.marker_rms(surfaces.with_positions(x), markers, registration)

    gradient = jax.jit(jax.grad(rms_at))(jnp.asarray(positions), found.registration)
    analytic = float(jnp.sum(gradient * direction))
    h = 1e-6
    fixed = (rms_at(positions + h * direction, found.registration)
             - rms_at(positions - h * direction, found.registration)) / (2 * h)
    assert float(fixed) == pytest.approx(analytic, rel=1e-6)
    # Started from the search's winner, the registration stays at its minimum.
    again = fitting.register(surfaces, markers, start=found.registration)
    assert again.converged and again.starts == 1
    assert again.rms_m == pytest.approx(found.rms_m, rel=1e-9)
    # Envelope theorem: re-registering at each perturbed shape (from the winner, as a fit
    # does) gives the same derivative.
    moved = [fitting.register(surfaces.with_positions(positions + s * h * direction),
                              markers, start=found.registration).rms_m for s in (1, -1)]
    assert (moved[0] - moved[1]) / (2 * h) == pytest.approx(analytic, rel=1e-3)
    assert abs(analytic) > 1e-3  # the check is not of a vanishing derivative


def test_canopy_distance_is_exact_inside_and_beside_a_triangle():
    corners = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5], [6, 5, 5]])
    surfaces = fitting.TubeSurfaces.from_segments(
        corners, [("LE", 3, 4, 0.1, 0.1)], canopy_triangles=[[0, 1, 2]])
    from fitting._shape.surfaces import canopy_distance
    points = jnp.asarray([[0.2, 0.2, 0.3], [2.0, 0.0, -0.4], [-1.0, -1.0, 0.0]])
    expected = [0.3, np.hypot(1.0, 0.4), np.sqrt(2.0)]
    np.testing.assert_allclose(canopy_distance(surfaces, points), expected, rtol=1e-12)


# ---------------------------------------------------------------- V3 null model

CAMPAIGN = REPO / "experiments" / "data" / "v3_hanging" / "campaign.toml"
PUBLISHED_UNDEFORMED_MM = {"P1_S": 695, "P1_PL1": 654, "P1_PL2": 639, "P1_TL1": 139,
                           "P1_TL2": 99}


@pytest.fixture(scope="module")
def v3_campaign():
    return fitting.read_campaign(CAMPAIGN)


@pytest.mark.parametrize("case", PUBLISHED_UNDEFORMED_MM)
def test_undeformed_v3_reproduces_the_published_null_scores(v3_campaign, case):
    """The campaign's tubes and canopy, undeformed, scored against each 0.15 bar case."""
    markers = fitting.load_markers(v3_campaign.case(case).markers)
    score = fitting.score_shape(fitting.campaign_tube_surfaces(v3_campaign), markers)
    assert score.registration.converged
    assert score.rms_mm == pytest.approx(PUBLISHED_UNDEFORMED_MM[case], abs=5.0)


# ---------------------------------------------------------------- files and CLI


def write(path, text):
    path.write_text(text)
    return path


def test_marker_units_mm_suffix_and_unsuffixed_metres(tmp_path):
    metres = fitting.load_markers(write(tmp_path / "m.csv", "group,idx_in_group,x,y,z\n"
                                                            "LE,0,1.5,2,3\n"))
    millimetres = fitting.load_markers(write(tmp_path / "mm.csv", "group,idx,x_mm,y_mm,z_mm\n"
                                                                  "LE,0,1500,2000,3000\n"))
    np.testing.assert_allclose(metres.position, [[1.5, 2, 3]])
    np.testing.assert_allclose(millimetres.position, [[1.5, 2, 3]])
    assert metres.line == (2,)


@pytest.mark.parametrize("text, line, column, expected", [
    ("group,idx_in_group,x_m,y_m\nLE,0,1,2\n", 1, None, "marker coordinates as x_m,y_m,z_m"),
    ("group,idx_in_group,x_m,y_m,z_m\nLE,0,1,two,3\n", 2, "y_m", "expected a finite number"),
    ("group,idx_in_group,x_m,y_m,z_m\nLE,0,1,2,3\nLE,0,1,2,4\n", 3, "idx_in_group",
     "appears twice (first on line 2)"),
    ("group,idx_in_group,x_m,y_m,z_m\n,0,1,2,3\n", 2, "group", "expected a group name"),
    ("group,idx_in_group,x_m,y_m,z_m\nLE,-1,1,2,3\n", 2, "idx_in_group", "integer >= 0"),
    ("group,idx_in_group,x_m,y_m,z_m\nLE,0,1,2\n", 2, None, "expected 5 fields"),
    ("group,x_m,y_m,z_m\nLE,1,2,3\n", 1, None, "missing column idx_in_group"),
    ("group,idx_in_group,x_m,y_m,z_m,x_mm\nLE,0,1,2,3,4\n", 1, None, "exactly one spelling"),
    ("", 1, None, "the file is empty"),
])
def test_bad_marker_files_name_file_line_column_and_expectation(tmp_path, text, line, column,
                                                                expected):
    path = write(tmp_path / "bad.csv", text)
    with pytest.raises(fitting.ShapeFileError) as raised:
        fitting.load_markers(path)
    problem = raised.value.problems[0]
    assert (problem.line, problem.column) == (line, column)
    assert expected in problem.message
    assert f"{path}:{line}" in str(raised.value)


def test_all_problems_reported_at_once_and_other_files_checked(tmp_path):
    path = write(tmp_path / "bad.csv", "group,idx_in_group,x_m,y_m,z_m\n"
                                       "LE,a,1,2,3\nLE,1,nan,2,3\nLE,2,1,2,inf\n")
    with pytest.raises(fitting.ShapeFileError) as raised:
        fitting.load_markers(path)
    assert [(p.line, p.column) for p in raised.value.problems] == [
        (2, "idx_in_group"), (3, "x_m"), (4, "z_m")]
    with pytest.raises(fitting.ShapeFileError, match="missing \\[1\\]"):
        fitting.load_positions(write(tmp_path / "p.csv", "node,x_m,y_m,z_m\n0,0,0,0\n2,1,1,1\n"))
    with pytest.raises(fitting.ShapeFileError, match="'radius_m': expected a radius >= 0"):
        fitting.load_tubes(write(tmp_path / "t.csv", "group,node_1,node_2,radius_m\n"
                                                     "LE,0,1,-0.1\n"))
    with pytest.raises(fitting.ShapeFileError, match="'node_2': expected an integer >= 0 "
                                                     "at most 1"):
        fitting.load_tubes(write(tmp_path / "t2.csv", "group,node_1,node_2,diameter_mm\n"
                                                      "LE,0,5,100\n"), node_count=2)


def test_cli_writes_scores_markers_and_figure_and_nothing_on_bad_input(kite, tmp_path):
    surfaces, _, groups, measured = kite
    nodes, segments = synthetic_kite()
    write(tmp_path / "positions.csv", "node,x_m,y_m,z_m\n" + "".join(
        f"{k},{x:.17g},{y:.17g},{z:.17g}\n" for k, (x, y, z) in enumerate(nodes)))
    write(tmp_path / "tubes.csv", "group,node_1,node_2,radius_start_mm,radius_end_mm\n" + "".join(
        f"{g},{a},{b},{1e3 * r0:.17g},{1e3 * r1:.17g}\n" for g, a, b, r0, r1 in segments))
    write(tmp_path / "markers.csv", "group,idx_in_group,x_m,y_m,z_m\n" + "".join(
        f"{g},{k},{x:.17g},{y:.17g},{z:.17g}\n"
        for k, (g, (x, y, z)) in enumerate(zip(groups, measured))))
    parser = argparse.ArgumentParser()
    add_score_shape(parser.add_subparsers())
    arguments = ["score-shape", "--markers", str(tmp_path / "markers.csv"), "--positions",
                 str(tmp_path / "positions.csv"), "--tubes", str(tmp_path / "tubes.csv")]
    args = parser.parse_args(arguments + ["--out", str(tmp_path / "out")])
    assert args.run(args) == 0
    scores = json.loads((tmp_path / "out" / "scores.json").read_text())
    direct = fitting.score_shape(surfaces, fitting.MarkerSet.from_arrays(groups, measured))
    assert scores["deformed"]["rms_mm"] == pytest.approx(direct.rms_mm, rel=1e-6)
    rows = (tmp_path / "out" / "markers.csv").read_text().splitlines()
    assert rows[0].startswith("group,idx,model_group,distance_mm") and len(rows) == 1 + len(groups)
    assert (tmp_path / "out" / "shape.png").read_bytes()[:4] == b"\x89PNG"
    write(tmp_path / "positions.csv", "node,x_m,y_m,z_m\n0,0,0,oops\n")
    args = parser.parse_args(arguments + ["--out", str(tmp_path / "bad")])
    assert args.run(args) == 2
    assert not (tmp_path / "bad").exists()
