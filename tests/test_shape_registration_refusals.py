"""Marker sets that cannot determine a rigid registration are refused, naming the file:
fewer than three distinct tube markers (three coincident markers used to give RMS 0,
"converged"), and markers all on one line (a rotation about it is free)."""

import argparse

import numpy as np
import pytest

import fitting
from fitting._cli.score_shape import add_score_shape

NODES = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.5, 0.0], [1.0, 0.0, 1.0]])
SEGMENTS = [("LE", 0, 1, 0.1, 0.1), ("LE", 1, 2, 0.1, 0.1), ("strut0", 1, 3, 0.05, 0.05)]


@pytest.mark.parametrize("points, reason", [
    ([[0.5, 0.1, 0.0]] * 3, "at least 3 distinct tube markers, found 1 distinct position"),
    ([[0.5, 0.1, 0.0]] * 2 + [[1.5, 0.3, 0.0]] * 2, "found 2 distinct positions among 4"),
    ([[0.1 * k, 0.2 * k, 0.3 * k] for k in range(5)], "all lie on one line"),
])
def test_degenerate_markers_are_refused_naming_the_file(tmp_path, points, reason):
    path = tmp_path / "markers.csv"
    path.write_text("group,idx_in_group,x_m,y_m,z_m\n" + "".join(
        f"LE,{k},{x},{y},{z}\n" for k, (x, y, z) in enumerate(points)))
    surfaces = fitting.TubeSurfaces.from_segments(NODES, SEGMENTS)
    with pytest.raises(ValueError, match=reason) as raised:
        fitting.register(surfaces, fitting.load_markers(path))
    assert str(path) in str(raised.value)
    # The command line says so and writes nothing (exit code 2).
    (tmp_path / "positions.csv").write_text("node,x_m,y_m,z_m\n" + "".join(
        f"{k},{x},{y},{z}\n" for k, (x, y, z) in enumerate(NODES)))
    (tmp_path / "tubes.csv").write_text("group,node_1,node_2,radius_m\n" + "".join(
        f"{g},{a},{b},{r}\n" for g, a, b, r, _ in SEGMENTS))
    parser = argparse.ArgumentParser()
    add_score_shape(parser.add_subparsers())
    args = parser.parse_args(["score-shape", "--markers", str(path), "--positions",
                              str(tmp_path / "positions.csv"), "--tubes",
                              str(tmp_path / "tubes.csv"), "--out", str(tmp_path / "out")])
    assert args.run(args) == 2
    assert not (tmp_path / "out").exists()
