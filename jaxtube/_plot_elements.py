"""Drawing point nodes, lines, pulleys, canopy nets and point masses on a 3-D axes.

Used by :func:`jaxtube._plot.deformed_shape_figure` when a structure has elements. Lines
whose name starts with ``"canopy"`` (spec ``[[canopy]]`` nets, imported kite_fem canopy
springs) are drawn as the canopy, the others as lines (bridle lines); taut and slack apart.
Ropes over pulleys are drawn as their two legs with the pulley node marked; point masses as
dots whose area grows with the mass; fixed points as black crosses.
"""

from __future__ import annotations

import numpy as np
from matplotlib.lines import Line2D
from mpl_toolkits.mplot3d.art3d import Line3DCollection

TAUT_LINE = dict(color="tab:brown", linewidth=1.0)
SLACK_LINE = dict(color="tab:red", linewidth=0.8, linestyle=(0, (2, 2)))
TAUT_CANOPY = dict(color="tab:cyan", linewidth=0.4, alpha=0.55)
SLACK_CANOPY = dict(color="tab:pink", linewidth=0.6, alpha=0.9, linestyle=(0, (1, 1)))
PULLEY = dict(color="tab:purple", linewidth=1.2)
MASS_COLOUR = "tab:olive"


def point_row_nodes(topology, node_count: int) -> np.ndarray:
    """Global node index of each row of ``state["point_position"]``: the structure's own
    point nodes (``node_count + k``), then the attachment points (their tube node)."""
    own = node_count + np.arange(len(topology.point_names), dtype=int)
    return np.concatenate([own, np.asarray(topology.attachment_nodes, dtype=int)]).astype(int)


def element_segments(structure, node_position) -> dict[str, np.ndarray]:
    """End points of the drawn elements, from every node's position ``[N_all, 3]`` [m].

    Returns ``line [L, 2, 3]``, ``pulley [Q, 3, 3]`` (end, pulley, end), ``mass [M, 3]``,
    ``fixed [F, 3]``.
    """
    topology = structure.elements
    nodes = point_row_nodes(topology, structure.node_count)
    position = np.asarray(node_position, dtype=float)

    def rows(ends, width):
        ends = np.asarray(ends, dtype=int).reshape(-1, width)
        return position[nodes[ends]] if ends.size else np.zeros((0, width, 3))

    own = structure.node_count + np.asarray(topology.fixed_points, dtype=int)
    return {
        "line": rows(topology.line_ends, 2),
        "pulley": rows(topology.pulley_ends, 3),
        "mass": position[nodes[np.asarray(topology.mass_points, dtype=int)]]
        if len(topology.mass_points) else np.zeros((0, 3)),
        "fixed": position[own] if own.size else np.zeros((0, 3)),
    }


def draw_elements(ax, structure, node_position, *, line_taut=None, pulley_taut=None,
                  point_mass=None) -> list:
    """Draw the elements of ``structure`` at ``node_position`` ``[N_all, 3]`` on a 3-D axes;
    returns legend handles. ``line_taut [L]``, ``pulley_taut [Q]``: bool states (``None``:
    all drawn as taut, e.g. for a reference shape). ``point_mass [M]`` [kg] sizes the dots.
    """
    topology = structure.elements
    if not topology.active:
        return []
    parts = element_segments(structure, node_position)
    handles = []
    lines = parts["line"]
    taut = (np.ones(len(lines), bool) if line_taut is None
            else np.asarray(line_taut, dtype=bool).reshape(-1))
    canopy = np.array([str(n).startswith("canopy") for n in topology.line_names], dtype=bool)
    for mask, style, label in (
            (canopy & taut, TAUT_CANOPY, "canopy, taut"),
            (canopy & ~taut, SLACK_CANOPY, "canopy, slack"),
            (~canopy & taut, TAUT_LINE, "line, taut"),
            (~canopy & ~taut, SLACK_LINE, "line, slack")):
        if np.any(mask):
            ax.add_collection3d(Line3DCollection(lines[mask], **style))
            handles.append(Line2D([], [], **style, label=f"{label} ({int(mask.sum())})"))
    ropes = parts["pulley"]
    if len(ropes):
        rope_taut = (np.ones(len(ropes), bool) if pulley_taut is None
                     else np.asarray(pulley_taut, dtype=bool).reshape(-1))
        legs = np.concatenate([ropes[:, :2], ropes[:, 1:]])
        state = np.concatenate([rope_taut, rope_taut])
        for mask, style, label in ((state, PULLEY, "rope over pulley, taut"),
                                   (~state, dict(PULLEY, linestyle=(0, (2, 2))),
                                    "rope over pulley, slack")):
            if np.any(mask):
                ax.add_collection3d(Line3DCollection(legs[mask], **style))
                handles.append(Line2D([], [], **style, label=f"{label} "
                                      f"({int(mask.sum()) // 2})"))
        ax.scatter(*ropes[:, 1].T, s=22, facecolors="none", edgecolors="tab:purple",
                   linewidths=1.0, depthshade=False)
        handles.append(Line2D([], [], linestyle="", marker="o", markerfacecolor="none",
                              color="tab:purple", label="pulley"))
    masses = parts["mass"]
    if len(masses):
        # Small dots: a kite has hundreds of lumped masses, which must not hide the frame.
        if point_mass is None:
            mass, area = None, np.full(len(masses), 4.0)
        else:
            mass = np.asarray(point_mass, dtype=float).reshape(-1)
            area = 2.0 + 30.0 * mass / max(float(mass.max()), 1e-12)
        ax.scatter(*masses.T, s=area, color=MASS_COLOUR, alpha=0.45, depthshade=False,
                   linewidths=0)
        handles.append(Line2D([], [], linestyle="", marker="o", color=MASS_COLOUR, alpha=0.6,
                              label=f"point masses ({len(masses)}"
                              + ("" if mass is None else f", {mass.sum():.3g} kg") + ")"))
    fixed = parts["fixed"]
    if len(fixed):
        ax.scatter(*fixed.T, s=90, marker="X", color="black", depthshade=False)
        handles.append(Line2D([], [], linestyle="", marker="X", color="black",
                              label="fixed point"))
    return handles
