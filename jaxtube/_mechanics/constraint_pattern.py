"""Which entries of the constraint Jacobian ``dc/dz`` can be nonzero: a static pattern for
the sparse KKT route (``jaxtube._solver.kkt_linear.SparseKKT``).

Every constraint of a structure (:func:`jaxtube._mechanics.energy.constraints`) is a function
of a few positions: the root position, tube nodes and segment ends, point nodes. A tube
node's position is ``root + sum_t step_t`` over the segments ``t`` on its position path
(``_position_sum_matrix``), and ``step_t`` depends on segment ``t``'s own unknowns only (its
rotation, and its shear where the model has shear). So row by row, in the order of
``constraints``:

- the root support: the root position (3 rows);
- every further support: that node's position (3 rows each);
- every loop closure ``(segment, node)``: that segment's end and that node (3 rows each);
- fixed points: the point's position; attachment ties: the point and its tube node
  (``jaxtube._elements.element_constraints``, 3 rows each);
- a displacement control: its node (1 row).

The pattern may hold entries that happen to be zero (it is a superset: a row of a support
depends on one coordinate of the root, its pattern holds all three); it must never miss one
(tested against the Jacobian at random states, ``tests/test_sparse_kkt.py``). Without it the
sparse route stores the Jacobian dense: on the TU Delft V3 kite (273 constraints on 984
unknowns) that made the KKT pattern a third dense (554,757 entries) and the route slower than
dense LU.
"""

from __future__ import annotations

import numpy as np

from .._elements import state_index
from .._structure.structure import Structure
from .kinematics import _position_sum_matrix


def constraint_jacobian_pattern(structure: Structure, state: dict,
                                control_node: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Static ``(rows, cols)`` (integer arrays of one length) of the entries of the
    constraint Jacobian that can be nonzero, over the state flattened as by
    ``jax.flatten_util.ravel_pytree``; ``control_node`` is the node of a displacement
    control (one more row), or ``None``."""
    index = state_index(state)
    root = root_columns(structure, index)
    if root.size:
        per_segment = [np.asarray(index["segment_rotation"])]
        if "segment_shear" in index:
            per_segment.append(np.asarray(index["segment_shear"]))
        segment_dofs = np.concatenate(per_segment, axis=1)  # [S, 3 or 5]
        on_path = _position_sum_matrix(structure) != 0  # [S, S]

    def segment_end(segment: int) -> np.ndarray:
        return np.concatenate([root, segment_dofs[on_path[segment]].reshape(-1)])

    return pattern_of_groups(constraint_groups(structure, index, control_node, root,
                                               segment_end))


def root_columns(structure: Structure, index: dict) -> np.ndarray:
    """The root position's columns in the flat state (none for a structure without tubes)."""
    if structure.segment_count > 0 and "segment_rotation" in index:
        return np.asarray(index["root_position"]).reshape(-1)
    return np.zeros(0, int)


def constraint_groups(structure: Structure, index: dict, control_node: int | None,
                      root: np.ndarray, segment_end) -> list[tuple[int, np.ndarray]]:
    """The constraints in the order of ``constraints``, as groups ``(row count, columns)``:
    the columns every row of the group may touch, given the columns of the root position
    (``root``) and of a segment's end (``segment_end(segment)``). In the state's own columns
    a segment's end is the root and every unknown on its path
    (:func:`constraint_jacobian_pattern`); in the factored form it is three auxiliary
    columns (:mod:`jaxtube._mechanics.constraint_factors`)."""

    def tube_node(node: int) -> np.ndarray:
        segment = structure.node_segment[node]
        return root if segment < 0 else segment_end(segment)

    def point(p: int) -> np.ndarray:
        return np.asarray(index["point_position"][p]).reshape(-1)

    groups: list[tuple[int, np.ndarray]] = []
    if root.size:
        if structure.supports:
            groups.append((3, root))
        for node, _kind in structure.supports[1:]:
            groups.append((3, tube_node(node)))
        for segment, node in structure.closures:
            groups.append((3, np.concatenate([segment_end(segment), tube_node(node)])))
    topology = structure.elements
    if topology.active:
        for p in topology.fixed_points:
            groups.append((3, point(p)))
        own = topology.own_point_count
        for k, node in enumerate(topology.attachment_nodes):
            groups.append((3, np.concatenate([point(own + k), tube_node(node)])))
    if control_node is not None:  # a tube node, or a point node after them
        groups.append((1, tube_node(control_node) if control_node < structure.node_count
                       else point(control_node - structure.node_count)))
    return groups


def pattern_of_groups(groups) -> tuple[np.ndarray, np.ndarray]:
    """``(rows, cols)`` of every group's rows times its (distinct) columns."""
    rows, cols, start = [], [], 0
    for count, columns in groups:
        columns = np.unique(columns)
        for r in range(start, start + count):
            rows.append(np.full(columns.size, r))
            cols.append(columns)
        start += count
    if not rows:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(rows).astype(np.int64), np.concatenate(cols).astype(np.int64)
