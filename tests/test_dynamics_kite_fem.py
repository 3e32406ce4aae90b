"""The kite_fem import's inertia: the nodal masses stay the whole mass and weight, the tubes
spin with the mass on their nodes (no solve: the small kite of ``kite_fem_mini``)."""

import numpy as np

import jaxtube as jt
from jaxtube._equilibrium import tube_reference_geometry

from .kite_fem_mini import SUSPENSION, mini_kite_arrays, write_mini_kite


def test_imported_tubes_spin_without_adding_mass_or_weight(tmp_path):
    path = tmp_path / "mini.npz"
    write_mini_kite(path)
    imported = jt.import_kite_fem(path, suspension=SUSPENSION, centre_node=3,
                                  tip_nodes=(7, 9))
    structure, params = imported.structure, imported.params
    held = [node for node in range(imported.model.node_count) if imported.node_index[node] < 0]
    node_mass = np.delete(mini_kite_arrays()["initial_conditions_array"][:, 6], held)
    geometry = tube_reference_geometry(structure, params)
    mass = jt.mass_properties(structure, params, geometry)
    # The whole mass (every direction) is the nodal masses, as the weight is.
    total = float(np.sum(mass.segment_mass) + np.sum(mass.point_mass))
    np.testing.assert_allclose(total, node_mass.sum(), rtol=1e-14)
    np.testing.assert_allclose(np.asarray(params.elements.point_mass).sum(), node_mass.sum(),
                               rtol=1e-14)
    assert np.all(np.asarray(mass.segment_mass) == 0.0)
    # Each tube spins with the mass on its nodes: sum of J_axial / r^2 is that mass.
    spin = np.asarray(params.inertia.spin_mass_per_length)
    assert spin.shape == (len(structure.tube_names),) and np.all(spin > 0)
    a = np.array([n[0] for n in structure.segment_nodes])
    b = np.array([n[1] for n in structure.segment_nodes])
    radius = 0.5 * (np.asarray(params.node_radius)[a] + np.asarray(params.node_radius)[b])
    ring = np.asarray(mass.segment_inertia)[:, 2] / radius**2
    tube = np.asarray(structure.segment_tube)
    per_tube = np.bincount(tube, weights=ring)
    length = np.bincount(tube, weights=np.asarray(geometry.length))
    np.testing.assert_allclose(per_tube, spin * length, rtol=1e-12)
    # No bending inertia from the spin-only mass: the segments turn across their axis free.
    np.testing.assert_array_equal(np.asarray(mass.segment_inertia)[:, :2], 0.0)
