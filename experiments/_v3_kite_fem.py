"""The V3 kite's tube surfaces read straight from kite_fem's ``initial.npz`` (numpy only).

A stop-gap until ``jt.read_kite_fem`` exists: the integrator may switch
:func:`v3_tube_surfaces` to it. Data: ``experiments/data/v3_hanging`` ("Structural model
data from awegroup/kite_fem (MIT, (c) 2025 Patrick Roeleveld); marker data from
pimjhaanen/photogrammetry_thesis (MIT, (c) 2026 PJ Haanen)").

Groups (README of the data): ``beam_matrix`` rows ``[node_1, node_2, diameter_m, ...]``;
rows 0-59 are ten chordwise chains of six beams from leading-edge nodes 1, 7, 13, 19, 25,
33, 39, 45, 51, 57 (the first and last close the wing tips and are not struts; the eight
inner ones are ``strut0`` .. ``strut7`` in that spanwise order), rows 60-87 the leading edge
along the odd wing nodes 1 .. 57 (``LE``). Each beam's radius is half its diameter
(constant along the beam). The canopy triangles are the 3-cliques of the canopy springs
(the first 618 rows of ``spring_matrix``; the last 46 are bridle lines) and tube beams: each canopy
quad with both diagonals gives four overlapping triangles.
"""

from pathlib import Path

import numpy as np

from fitting import TubeSurfaces

DATA = Path(__file__).resolve().parent / "data" / "v3_hanging"
CASES = ("P1_S", "P1_PL1", "P1_PL2", "P1_TL1", "P1_TL2")
LEADING_EDGE_STRUT_ROOTS = (1, 7, 13, 19, 25, 33, 39, 45, 51, 57)


def v3_tube_surfaces(positions=None, npz=DATA / "kite_fem" / "initial.npz") -> TubeSurfaces:
    """The V3 tubes (and canopy) at ``positions [247, 3]`` [m] (default: ``initial.npz``)."""
    data = np.load(npz, allow_pickle=True)
    beams = data["beam_matrix"]
    nodes = beams[:, :2].astype(int)
    chains = {int(row[0]): k for k, row in enumerate(nodes[:60:6])}
    assert tuple(sorted(chains)) == LEADING_EDGE_STRUT_ROOTS, "unexpected beam_matrix layout"
    rows = []
    for number, root in enumerate(LEADING_EDGE_STRUT_ROOTS[1:-1]):
        first = 6 * chains[root]
        rows += [(f"strut{number}", *nodes[b], beams[b, 2] / 2, beams[b, 2] / 2)
                 for b in range(first, first + 6)]
    rows += [("LE", *nodes[b], beams[b, 2] / 2, beams[b, 2] / 2) for b in range(60, 88)]
    if positions is None:
        positions = data["initial_conditions_array"][:, :3]
    return TubeSurfaces.from_segments(positions, rows, canopy_triangles(data))


def canopy_triangles(data) -> np.ndarray:
    """``[t, 3]`` triangles of the canopy: 3-cliques of canopy springs and tube beams."""
    springs = data["spring_matrix"][:, :2].astype(int)
    assert len(springs) == 664, "expected 618 canopy springs then 46 bridle lines"
    edges = {tuple(sorted(e)) for e in data["beam_matrix"][:, :2].astype(int)}
    edges |= {tuple(sorted(e)) for e in springs[:618]}
    neighbours: dict[int, set] = {}
    for a, b in edges:
        neighbours.setdefault(a, set()).add(b)
        neighbours.setdefault(b, set()).add(a)
    triangles = {tuple(sorted((a, b, c))) for a, b in edges
                 for c in neighbours[a] & neighbours[b]}
    return np.asarray(sorted(triangles), int)


def kite_fem_state(case: int) -> np.ndarray:
    """kite_fem's solved positions ``[247, 3]`` [m] of load case 1-5."""
    state = np.load(DATA / "kite_fem" / "states" / f"load_case_{case}.npz")
    return state["coords_current"].reshape(-1, 3)
