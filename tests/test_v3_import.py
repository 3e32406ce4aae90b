"""The TU Delft V3 kite imported from kite_fem (``initial.npz``, bundled with its licence in
``experiments/data/v3_hanging``): counts and mass. The kite hung from nodes 82 and 116
(converged, reactions equal to the weight, every line's state reported) is tested in
``tests/test_v3_hanging.py``, on the one compiled hang that file shares; ``jaxtube simulate
--kite-fem`` is tested on the small kite in ``tests/test_kite_fem_hang.py``."""

from pathlib import Path

import numpy as np
import pytest

import jaxtube as jt

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
