"""The elements' share of the energy, the constraints, the Lagrangian Hessian and the report.

Everything here is a function of the point unknowns ``state["point_position"]`` ``[P, 3]``
[m] (rows: see :class:`ElementTopology`) and, for the ties of attachment points, of the
tube node positions.

Energy [J]: line and pulley energies (``lines.py``) minus the work of the point masses
under gravity and of the dead point forces, ``- sum m g . p - sum F . p``.

Constraints [m], in this order: ``p_k - X_k`` for every fixed point, then
``p_j - x_node(j)`` for every attachment point. With ``L = E + lambda . c``, stationarity in
``p`` gives ``lambda = -dE/dp``, the force the elements (lines, pulleys, masses) apply to
that point [N]: minus the reaction of a fixed point; for a tie, the force the elements
apply to the tube node.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .lines import distance, line_energy, pulley_energy, pulley_length, tension
from .points import ElementParameters, ElementTopology


def _rows(values: Array, index) -> Array:
    index = np.asarray(index, dtype=np.int32).reshape(-1)
    return values[index]


def initial_point_position(topology: ElementTopology, elements: ElementParameters,
                           tube_node_position: Array) -> Array:
    """Reference rows of ``state["point_position"]`` ``[P, 3]`` [m]: the structure's point
    nodes, then the reference positions of the attached tube nodes."""
    attached = _rows(tube_node_position, topology.attachment_nodes)
    return jnp.concatenate([elements.point_position, attached], axis=0)


def element_energy(topology: ElementTopology, elements: ElementParameters, gravity: Array,
                   point_position: Array) -> Array:
    """Line and pulley strain energy minus the potential of masses and point forces [J]."""
    return (element_strain_energy(topology, elements, point_position)
            + element_load_potential(topology, elements, gravity, point_position))


def element_strain_energy(topology: ElementTopology, elements: ElementParameters,
                          point_position: Array) -> Array:
    """Strain energy of the tension-only lines and pulley ropes [J]."""
    energy = jnp.zeros((), point_position.dtype)
    smoothing = elements.tension_smoothing
    if topology.line_ends:
        ends = np.asarray(topology.line_ends, dtype=np.int32)
        energy = energy + jnp.sum(line_energy(
            point_position[ends[:, 0]], point_position[ends[:, 1]], elements.line_stiffness,
            elements.line_rest_length, smoothing))
    if topology.pulley_ends:
        ends = np.asarray(topology.pulley_ends, dtype=np.int32)
        energy = energy + jnp.sum(pulley_energy(
            point_position[ends[:, 0]], point_position[ends[:, 1]], point_position[ends[:, 2]],
            elements.pulley_stiffness, elements.pulley_rest_length, smoothing))
    return energy


def element_load_potential(topology: ElementTopology, elements: ElementParameters,
                           gravity: Array, point_position: Array) -> Array:
    """Potential of the point masses under gravity and of the point nodes' dead forces [J]."""
    energy = jnp.zeros((), point_position.dtype)
    if topology.mass_points:
        weight = elements.point_mass[:, None] * gravity[None, :]
        energy = energy - jnp.sum(weight * _rows(point_position, topology.mass_points))
    own = topology.own_point_count
    if own:
        energy = energy - jnp.sum(elements.point_force * point_position[:own])
    return energy


def element_constraints(topology: ElementTopology, elements: ElementParameters,
                        point_position: Array, tube_node_position: Array | None) -> Array:
    """Fixed points, then attachment ties, flattened ``[3 (F + A)]`` [m]."""
    parts = [jnp.zeros((0,), point_position.dtype)]
    if topology.fixed_points:
        rows = topology.fixed_points
        parts.append((_rows(point_position, rows)
                      - _rows(elements.point_position, rows)).reshape(-1))
    if topology.attachment_nodes:
        own = topology.own_point_count
        tied = point_position[own:]
        parts.append((tied - _rows(tube_node_position, topology.attachment_nodes)).reshape(-1))
    return jnp.concatenate(parts)


def element_hessian_blocks(topology: ElementTopology, elements: ElementParameters,
                           point_position: Array, point_index: np.ndarray):
    """The elements' exact Lagrangian Hessian as blocks ``[(rows, cols, values), ...]``.

    One block per line (6 x 6 over its two end points) and per pulley (9 x 9 over its
    three nodes), each from ``jax.hessian`` of the element energy, vmapped; ``rows`` and
    ``cols`` are static integer arrays of the same shape as ``values`` (positions in the
    flattened state; ``point_index`` ``[P, 3]`` is that of ``state["point_position"]``).
    Masses, point forces, fixed points and ties are linear in the point positions and add
    no block.
    """
    blocks = []
    smoothing = elements.tension_smoothing
    if topology.line_ends:
        ends = np.asarray(topology.line_ends, dtype=np.int32)

        def one_line(dofs, stiffness, rest_length):
            return line_energy(dofs[:3], dofs[3:], stiffness, rest_length, smoothing)

        dofs = jnp.concatenate([point_position[ends[:, 0]], point_position[ends[:, 1]]], 1)
        values = jax.vmap(jax.hessian(one_line))(dofs, elements.line_stiffness,
                                                 elements.line_rest_length)
        index = np.concatenate([point_index[ends[:, 0]], point_index[ends[:, 1]]], axis=1)
        blocks.append((np.broadcast_to(index[:, :, None], values.shape),
                       np.broadcast_to(index[:, None, :], values.shape), values))
    if topology.pulley_ends:
        ends = np.asarray(topology.pulley_ends, dtype=np.int32)

        def one_pulley(dofs, stiffness, rest_length):
            return pulley_energy(dofs[:3], dofs[3:6], dofs[6:], stiffness, rest_length,
                                 smoothing)

        dofs = jnp.concatenate([point_position[ends[:, k]] for k in range(3)], axis=1)
        values = jax.vmap(jax.hessian(one_pulley))(dofs, elements.pulley_stiffness,
                                                   elements.pulley_rest_length)
        index = np.concatenate([point_index[ends[:, k]] for k in range(3)], axis=1)
        blocks.append((np.broadcast_to(index[:, :, None], values.shape),
                       np.broadcast_to(index[:, None, :], values.shape), values))
    return blocks


def line_report(topology: ElementTopology, elements: ElementParameters,
                point_position: Array) -> dict[str, Array]:
    """Lengths [m], tensions [N] and taut flags of the lines and pulley ropes.

    A line is *taut* when it carries tension, i.e. its strain exceeds ``-delta / 2``
    (``delta`` the tension smoothing; between ``-delta / 2`` and 0 it carries the blend's
    tension, at most ``k L0 delta / 8``).
    """
    smoothing = elements.tension_smoothing
    dtype = point_position.dtype
    if topology.line_ends:
        ends = np.asarray(topology.line_ends, dtype=np.int32)
        line_length = distance(point_position[ends[:, 0]], point_position[ends[:, 1]])
    else:
        line_length = jnp.zeros((0,), dtype)
    line_tension = tension(line_length, elements.line_stiffness, elements.line_rest_length,
                           smoothing)
    if topology.pulley_ends:
        ends = np.asarray(topology.pulley_ends, dtype=np.int32)
        rope = pulley_length(point_position[ends[:, 0]], point_position[ends[:, 1]],
                             point_position[ends[:, 2]])
    else:
        rope = jnp.zeros((0,), dtype)
    pulley_tension = tension(rope, elements.pulley_stiffness, elements.pulley_rest_length,
                             smoothing)
    return {
        "line_length": line_length,
        "line_tension": line_tension,
        "line_taut": line_tension > 0.0,
        "pulley_length": rope,
        "pulley_tension": pulley_tension,
        "pulley_taut": pulley_tension > 0.0,
    }


def state_index(state: dict) -> dict:
    """Positions of every state entry in the flattened state (``ravel_pytree`` order): the
    same PyTree with integer arrays of the entries' shapes."""
    leaves, treedef = jax.tree_util.tree_flatten(state)
    offsets = np.cumsum([0] + [leaf.size for leaf in leaves])
    return treedef.unflatten([np.arange(o, o + leaf.size).reshape(leaf.shape)
                              for o, leaf in zip(offsets, leaves)])


def dense_from_blocks(state: dict, blocks: list) -> Array:
    """Scatter-add Hessian blocks ``(rows, cols, values)`` into the dense ``[n, n]`` matrix
    over the flattened ``state`` (the interim assembly until the sparse KKT path)."""
    leaves = jax.tree_util.tree_leaves(state)
    n = sum(leaf.size for leaf in leaves)
    if not blocks:
        return jnp.zeros((n, n), leaves[0].dtype)
    rows = np.concatenate([np.asarray(r).reshape(-1) for r, _, _ in blocks])
    cols = np.concatenate([np.asarray(c).reshape(-1) for _, c, _ in blocks])
    values = jnp.concatenate([v.reshape(-1) for _, _, v in blocks])
    return jnp.zeros((n, n), values.dtype).at[rows, cols].add(values)


def element_results(structure, params, state: dict, multipliers: Array,
                    tube_node_position: Array | None) -> dict[str, Array]:
    """Point, line, pulley and tie results of a solution (fields of ``Solution``).

    The element multipliers follow those of the supports and loops (3 each) when the
    structure has tubes: fixed points, then ties (``element_constraints``).
    """
    topology = structure.elements
    tube_nodes = jnp.zeros((0, 3)) if tube_node_position is None else tube_node_position
    own = topology.own_point_count
    points = state["point_position"] if topology.active else jnp.zeros((0, 3))
    report = line_report(topology, params.elements, points)
    start = (0 if tube_node_position is None
             else 3 * (len(structure.supports) + len(structure.closures)))
    fixed = len(topology.fixed_points)
    tie = multipliers[start + 3 * fixed: start + 3 * (fixed + len(topology.attachment_nodes))]
    return dict(
        node_position=jnp.concatenate([tube_nodes, points[:own]], axis=0),
        point_position=points[:own],
        fixed_point_reaction=-jnp.reshape(multipliers[start: start + 3 * fixed], (fixed, 3)),
        attachment_force=jnp.reshape(tie, (-1, 3)),
        **report,
    )
