"""A small kite in kite_fem's file format (for tests): a five-node leading edge, two struts,
a few canopy springs, bridle lines to two suspension nodes, a pulley and a held node.

Frame as kite_fem's V3 model: gravity along +z, the suspension at z = 0, the kite below it
(larger z). kite_fem numbering: 0 held (no element), 1-5 leading edge (y from -1 to 1), 6-7
and 8-9 the struts from nodes 2 and 4, 10 a bridle node carrying the pulley, 11 and 12 the
suspension.
"""

import numpy as np

SUSPENSION = (11, 12)


def mini_kite_arrays() -> dict[str, np.ndarray]:
    y = np.linspace(-1.0, 1.0, 5)
    leading_edge = np.stack([np.zeros(5), y, 2.0 + 0.4 * (1.0 - y**2)], axis=1)
    positions = np.zeros((13, 3))
    positions[0] = (0.0, 0.0, -0.5)
    positions[1:6] = leading_edge
    for root, first in ((2, 6), (4, 8)):
        for k, dx in enumerate((0.4, 0.8)):
            positions[first + k] = leading_edge[root - 1] + (dx, 0.0, 0.05 * (k + 1))
    positions[10] = (0.25, 0.0, 1.2)
    positions[11] = (0.0, -0.4, 0.0)
    positions[12] = (0.0, 0.4, 0.0)
    mass = np.full(13, 0.1)
    mass[[0, 11, 12]] = 0.0
    conditions = np.zeros((13, 8))
    conditions[:, :3] = positions
    conditions[:, 6] = mass
    conditions[0, 7] = 1.0
    beams = [(2, 6, 0.06), (6, 7, 0.05), (4, 8, 0.06), (8, 9, 0.05),
             (1, 2, 0.09), (2, 3, 0.10), (3, 4, 0.10), (4, 5, 0.09)]
    beam_matrix = np.array([(a, b, d, 0.2, np.linalg.norm(positions[a] - positions[b]))
                            for a, b, d in beams])
    springs = [(7, 9, 2000.0), (1, 7, 2000.0), (5, 9, 2000.0), (3, 7, 2000.0), (3, 9, 2000.0),
               (11, 1, 5000.0), (11, 2, 5000.0), (12, 4, 5000.0), (12, 5, 5000.0),
               (11, 10, 5000.0), (12, 10, 5000.0)]
    spring_matrix = np.array([(str(a), str(b), str(k), "0.0",
                               repr(float(np.linalg.norm(positions[a] - positions[b]))),
                               "noncompressive") for a, b, k in springs])
    rope = (np.linalg.norm(positions[6] - positions[10])
            + np.linalg.norm(positions[8] - positions[10]))
    pulley_matrix = np.array([(6.0, 10.0, 8.0, 5000.0, 0.0, rope)])
    return {"initial_conditions_array": conditions, "beam_matrix": beam_matrix,
            "spring_matrix": spring_matrix, "pulley_matrix": pulley_matrix}


def write_mini_kite(path) -> None:
    np.savez(path, **mini_kite_arrays())
