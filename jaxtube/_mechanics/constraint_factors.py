"""The constraint Jacobian in factored form, for the augmented sparse KKT route.

Every constraint (:func:`jaxtube._mechanics.energy.constraints`: supports, loop closures,
fixed points, attachment ties, a displacement control) is affine in positions only: the
root, the segment ends ``w_s`` (a tube node is the end of its tree segment, or the root) and
the point nodes. The segment ends follow the tree::

    w_s = w_parent(s) + step_s(z),    step_s = Q_s0 exp(phi_s) e_s(gamma_s)

(``w_parent`` the root for a segment on the ground; ``jaxtube._mechanics.kinematics``). So the
constraint Jacobian is ``J = C_z + C_w G^{-1} F`` with

- ``G`` (``[p, p]``, ``p = 3 S``): identity minus the parent's end, constant;
- ``F`` (``[p, n]``): ``d step_s / d(phi_s, gamma_s)`` per segment (a 3 x 3 or 3 x 5 block),
  and the root's identity for the segments on the ground;
- ``C_z``, ``C_w``: the constraints' derivatives with respect to the state's own positions
  (root, point nodes) and to the segment ends: entries of +-1 and a control's direction.

These are the blocks of :class:`jaxtube._solver.kkt_augmented.ConstraintFactors`: the rows
``[-F  G]`` (tree) and ``[C_z  C_w]`` (constraints) over the columns ``(z, w)``. Every row
is local, so KLU does not fill in along the tree paths as it does with the rows of ``J``
itself (``jaxtube._solver.kkt_augmented`` explains why and what it saves).
``tests/test_sparse_kkt.py`` checks ``C_z + C_w G^{-1} F`` against the autodiff Jacobian.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .._elements import state_index
from .._rotation import rotation_matrix
from .._solver.kkt_augmented import ConstraintFactors
from .._structure.structure import GROUND, Structure
from .constraint_pattern import constraint_groups, pattern_of_groups, root_columns
from .energy import constraints
from .geometry import ReferenceGeometry
from .kinematics import Configuration


def constraint_factors(structure: Structure, geometry: ReferenceGeometry, params, control,
                       state: dict) -> ConstraintFactors | None:
    """The :class:`ConstraintFactors` of the structure's constraints at ``state`` (module
    docstring), or ``None`` for a structure without tubes (its Jacobian is already local).
    ``control``: ``None`` or ``(node, direction [3], displacement [m])``."""
    index = state_index(state)
    root = root_columns(structure, index)
    if not root.size:
        return None
    n = sum(int(np.size(v)) for v in jax.tree_util.tree_leaves(index))
    count = structure.segment_count
    ends = n + np.arange(3 * count).reshape(count, 3)  # the columns of w

    # Tree rows: dw_s - dw_parent - F_s d(dofs_s) = 0, three per segment.
    dofs_index = [np.asarray(index["segment_rotation"])]
    if "segment_shear" in state:
        dofs_index.append(np.asarray(index["segment_shear"]))
    dofs_index = np.concatenate(dofs_index, axis=1)  # [S, q]
    rows = np.arange(3 * count).reshape(count, 3)
    parent = np.asarray(structure.position_parent)
    parent_cols = np.where((parent == GROUND)[:, None], root[None, :],
                           ends[np.maximum(parent, 0)])
    step_jacobian = jax.vmap(jax.jacfwd(_segment_step))(
        _segment_dofs(state), geometry.frame, geometry.end_vector, geometry.length)
    dtype = step_jacobian.dtype
    tree = [
        (rows, ends, jnp.ones((count, 3), dtype)),
        (rows, parent_cols, -jnp.ones((count, 3), dtype)),
        (np.broadcast_to(rows[:, :, None], step_jacobian.shape),
         np.broadcast_to(dofs_index[:, None, :], step_jacobian.shape), -step_jacobian),
    ]

    # Constraint rows: derivatives with respect to (root, w, points), gathered at the
    # pattern of the constraint groups with a segment's end as its three columns of w.
    def segment_end_columns(segment: int) -> np.ndarray:
        return ends[segment]

    node = None if control is None else control[0]
    c_rows, c_cols = pattern_of_groups(constraint_groups(structure, index, node, root,
                                                         segment_end_columns))
    points = "point_position" in state
    position_cols = np.concatenate(
        [root, ends.reshape(-1)]
        + ([np.asarray(index["point_position"]).reshape(-1)] if points else []))
    where = np.full(n + 3 * count, -1, np.int64)
    where[position_cols] = np.arange(position_cols.size)

    def affine(positions):
        root_position = positions[:3]
        segment_end = positions[3:3 + 3 * count].reshape(count, 3)
        moved = dict(state, root_position=root_position)
        if points:
            moved["point_position"] = positions[3 + 3 * count:].reshape(-1, 3)
        config = _configuration(structure, root_position, segment_end)
        return constraints(structure, config, moved, params, control)

    at = jnp.concatenate(
        [state["root_position"], jnp.zeros(3 * count, dtype)]
        + ([jnp.reshape(state["point_position"], (-1,))] if points else []))
    dense = jax.jacfwd(affine)(at)  # [m, 3 + 3 S + 3 P], constant: affine constraints
    constraint = [(c_rows, c_cols, dense[c_rows, where[c_cols]])]
    return ConstraintFactors(3 * count, tree, constraint)


def _segment_dofs(state: dict):
    if "segment_shear" in state:
        return jnp.concatenate([state["segment_rotation"], state["segment_shear"]], axis=1)
    return state["segment_rotation"]


def _segment_step(dofs, frame0, end_vector, length):
    """``step_s = Q_s0 exp(phi_s) (e_s + L_s (gamma_1, gamma_2, 0))`` [m] (as
    ``kinematics.segment_steps``) of one segment's unknowns ``dofs`` ``[3]`` or ``[5]``."""
    vector = end_vector
    if dofs.shape[0] == 5:
        vector = end_vector + length * jnp.concatenate([dofs[3:], jnp.zeros(1, dofs.dtype)])
    return frame0 @ (rotation_matrix(dofs[:3]) @ vector)


def _configuration(structure: Structure, root_position, segment_end) -> Configuration:
    """A configuration from the root and the segment ends (the frames are not needed by
    the constraints and are left as zeros)."""
    parent = np.asarray(structure.position_parent)
    start = jnp.where((parent == GROUND)[:, None], root_position,
                      segment_end[np.maximum(parent, 0)])
    node_segment = np.asarray(structure.node_segment, dtype=np.int32)
    nodes = jnp.where((node_segment >= 0)[:, None], segment_end[np.maximum(node_segment, 0)],
                      root_position)
    count = segment_end.shape[0]
    return Configuration(frame=jnp.zeros((count, 3, 3), segment_end.dtype),
                         segment_start=start, segment_end=segment_end, node_position=nodes)
