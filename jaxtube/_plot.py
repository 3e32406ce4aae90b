"""Figures of a solved load path: force-deflection curve and deformed shape.

Figures are built with matplotlib's object-oriented API (``matplotlib.figure.Figure``, no
``pyplot``), so they never open a window, never touch pyplot's global state and render
with the Agg backend when saved. Every function returns the ``Figure``; save it with
``fig.savefig(path)``.

Joint regimes follow the laws (``regime``): 0 unwrinkled, 1 wrinkled, 2 collapsed.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from mpl_toolkits.mplot3d import Axes3D  # noqa: F401  (registers the "3d" projection)

from ._plot_elements import draw_elements
from ._structure import Structure

REGIME_NAMES = ("unwrinkled", "wrinkled", "collapsed")
REGIME_COLOURS = ("tab:green", "tab:orange", "tab:red")
FAILED_COLOUR = "black"


def force_deflection_figure(
    displacement_mm, force_N, worst_regime, converged, *, title: str = "",
    xlabel: str = "displacement [mm]", ylabel: str = "force [N]",
) -> Figure:
    """Force against displacement, one point per step coloured by its worst joint regime.

    Arguments (all shape ``[K]``, one entry per step): ``displacement_mm``, ``force_N``,
    ``worst_regime`` (0/1/2), ``converged`` (bool). Steps that did not converge are drawn as
    black crosses (or dotted lines at the one finite value) and counted in the legend; the
    line joins the origin and the converged steps only.
    """
    displacement = np.asarray(displacement_mm, dtype=float)
    force = np.asarray(force_N, dtype=float)
    regime = np.asarray(worst_regime, dtype=int)
    converged = np.asarray(converged, dtype=bool)
    fig = Figure(figsize=(7.0, 4.8), layout="constrained")
    ax = fig.add_subplot()
    good = converged & np.isfinite(displacement) & np.isfinite(force)
    ax.plot(np.concatenate([[0.0], displacement[good]]), np.concatenate([[0.0], force[good]]),
            color="0.6", linewidth=1.2, zorder=1)
    handles = []
    for value, (name, colour) in enumerate(zip(REGIME_NAMES, REGIME_COLOURS)):
        chosen = good & (regime == value)
        ax.scatter(displacement[chosen], force[chosen], s=22, color=colour, zorder=2)
        handles.append(Line2D([], [], linestyle="", marker="o", color=colour,
                              label=f"{name} ({int(chosen.sum())})"))
    failed = ~converged
    if failed.any():
        shown = failed & np.isfinite(displacement) & np.isfinite(force)
        ax.scatter(displacement[shown], force[shown], s=40, marker="x", color=FAILED_COLOUR,
                   zorder=3)
        # A failed step with one non-finite value is marked by a line at the other one.
        for x in displacement[failed & np.isfinite(displacement) & ~np.isfinite(force)]:
            ax.axvline(x, color=FAILED_COLOUR, linestyle=":", linewidth=0.8)
        for y in force[failed & ~np.isfinite(displacement) & np.isfinite(force)]:
            ax.axhline(y, color=FAILED_COLOUR, linestyle=":", linewidth=0.8)
        handles.append(Line2D([], [], linestyle="", marker="x", color=FAILED_COLOUR,
                              label=f"did not converge ({int(failed.sum())})"))
    ax.legend(handles=handles, title="worst joint regime", loc="best")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    if title:
        ax.set_title(title)
    return fig


def _node_regimes(joint_node, joint_regime, node_count: int) -> np.ndarray:
    """Worst regime of the joints at each node, ``[N]`` (-1 where there is no joint)."""
    out = np.full(node_count, -1, dtype=int)
    np.maximum.at(out, np.asarray(joint_node, dtype=int), np.asarray(joint_regime, dtype=int))
    return out


def deformed_shape_figure(
    structure: Structure, reference_position, node_position, converged, *,
    joint_node=(), joint_regime=None, point_force=None, control=None, distributed=None,
    intermediate: int = 3, title: str = "", line_taut=None, pulley_taut=None,
    point_mass=None, gravity=None,
) -> Figure:
    """Undeformed (grey) and deformed shape in 3-D, with supports and loads.

    Arguments:
        structure: the topology (tubes, supports).
        reference_position: ``[N, 3]`` reference node positions [m].
        node_position: ``[K, N, 3]`` deformed node positions per step [m].
        converged: ``[K]`` bool. The last converged step is drawn in full, with up to
            ``intermediate`` earlier converged steps faded; if no step converged, only the
            undeformed shape is drawn.
        joint_node: ``[J]`` node index of each spring joint.
        joint_regime: ``[K, J]`` regimes, used to colour the joints of the drawn step.
        point_force: ``[K, N, 3]`` applied point forces [N] (drawn as blue arrows at the
            drawn step).
        control: optional ``(node, direction [3], force [K])``: the displacement actuator,
            drawn as a magenta arrow of ``force * direction``.
        distributed: ``[K, T, 3]`` distributed load per tube [N/m] (line load plus
            self-weight), drawn as small teal arrows at the segment midpoints of the drawn
            step, scaled on their own.
        line_taut: ``[K, L]`` bool: the state of each line. A structure with point nodes,
            lines, pulleys or masses has them drawn at the drawn step
            (``jaxtube._plot_elements``); node arrays then hold every node (tube nodes, then
            point nodes).
        pulley_taut: ``[K, Q]`` bool: the state of each pulley rope.
        point_mass: ``[M]`` [kg] sizes the masses.
        gravity: ``[3]``; when it points along +z the z axis is turned so that it points
            down on the page (a kite hung in kite_fem's frame).
    """
    reference = np.asarray(reference_position, dtype=float)
    positions = np.asarray(node_position, dtype=float)
    converged = np.asarray(converged, dtype=bool) & np.all(
        np.isfinite(positions), axis=(1, 2))
    fig = Figure(figsize=(8.0, 7.0), layout="constrained")
    ax = fig.add_subplot(projection="3d")

    def draw(points, **style):
        for ids in structure.tube_node_ids:
            xyz = points[list(ids)]
            ax.plot(xyz[:, 0], xyz[:, 1], xyz[:, 2], **style)
            style.pop("label", None)

    draw(reference, color="0.65", linewidth=1.5, linestyle="--", label="undeformed")
    cloud = [reference]
    done = np.flatnonzero(converged)
    handles = [Line2D([], [], color="0.65", linestyle="--", label="undeformed")]
    shown = None
    if done.size:
        shown = int(done[-1])
        earlier = done[:-1]
        if intermediate > 0 and earlier.size:
            picks = earlier[np.unique(np.linspace(0, earlier.size - 1,
                                                  min(intermediate, earlier.size)).round()
                                      .astype(int))]
            for k in picks:
                draw(positions[k], color="tab:blue", alpha=0.25, linewidth=1.2)
                cloud.append(positions[k])
            handles.append(Line2D([], [], color="tab:blue", alpha=0.25,
                                  label="intermediate steps"))
        draw(positions[shown], color="tab:blue", linewidth=2.2)
        cloud.append(positions[shown])
        handles.append(Line2D([], [], color="tab:blue", linewidth=2.2,
                              label=f"deformed (step {shown + 1})"))
        if joint_regime is not None and len(joint_node):
            node_regime = _node_regimes(joint_node, np.asarray(joint_regime)[shown],
                                        reference.shape[0])
            for value, (name, colour) in enumerate(zip(REGIME_NAMES, REGIME_COLOURS)):
                ids = np.flatnonzero(node_regime == value)
                if ids.size:
                    xyz = positions[shown][ids]
                    ax.scatter(xyz[:, 0], xyz[:, 1], xyz[:, 2], s=18, color=colour,
                               depthshade=False)
                    handles.append(Line2D([], [], linestyle="", marker="o", color=colour,
                                          label=f"joint {name}"))
    current = positions[shown] if shown is not None else reference
    if structure.elements.active:
        handles += draw_elements(
            ax, structure, current,
            line_taut=None if line_taut is None or shown is None else np.asarray(line_taut)[shown],
            pulley_taut=(None if pulley_taut is None or shown is None
                         else np.asarray(pulley_taut)[shown]),
            point_mass=point_mass)

    for node, kind in structure.supports:
        marker = "s" if kind == "clamped" else "^"
        x, y, z = current[node]
        ax.scatter([x], [y], [z], s=150, marker=marker, facecolors="none",
                   edgecolors="black", linewidths=1.5, depthshade=False)
    for kind, marker in (("clamped", "s"), ("pinned", "^")):
        if any(k == kind for _, k in structure.supports):
            handles.append(Line2D([], [], linestyle="", marker=marker, color="black",
                                  markerfacecolor="none", label=f"{kind} support"))

    cloud = np.concatenate(cloud)
    size = float(np.max(np.ptp(cloud, axis=0))) or 1.0
    arrows = []  # (start [3], vector [3] in N, colour)
    if point_force is not None and shown is not None:
        forces = np.asarray(point_force, dtype=float)[shown]
        for node in np.flatnonzero(np.linalg.norm(forces, axis=1) > 0):
            arrows.append((current[node], forces[node], "tab:blue", "applied load"))
    if control is not None and shown is not None:
        node, direction, force = control
        value = float(np.asarray(force)[shown])
        if np.isfinite(value) and value != 0.0:
            arrows.append((current[node], value * np.asarray(direction, dtype=float),
                           "tab:purple", "actuator force"))
    if distributed is not None and shown is not None:
        per_tube = np.asarray(distributed, dtype=float)[shown]
        strongest = float(np.max(np.linalg.norm(per_tube, axis=1), initial=0.0))
        for t, ids in enumerate(structure.tube_node_ids):
            q = per_tube[t]
            if strongest == 0.0 or not np.any(q):
                continue
            xyz = current[list(ids)]
            heads = 0.5 * (xyz[1:] + xyz[:-1])
            drawn = 0.08 * size * q / strongest
            tails = heads - drawn
            ax.quiver(tails[:, 0], tails[:, 1], tails[:, 2], *np.broadcast_to(
                drawn, tails.shape).T, color="tab:cyan", arrow_length_ratio=0.3,
                linewidth=0.8)
        if strongest > 0.0:
            handles.append(Line2D([], [], color="tab:cyan", marker=">", label=(
                f"line load / self-weight (up to {strongest:.3g} N/m)")))
    if arrows:
        largest = max(np.linalg.norm(vector) for _, vector, _, _ in arrows)
        labels = set()
        for start, vector, colour, label in arrows:
            drawn = 0.25 * size * vector / largest
            tail = start - drawn  # arrows end at the node they push on
            ax.quiver(*tail, *drawn, color=colour, arrow_length_ratio=0.25, linewidth=1.8)
            ax.text(*(tail - 0.05 * drawn), f"{np.linalg.norm(vector):.3g} N", color=colour,
                    fontsize=8)
            cloud = np.concatenate([cloud, tail[None]])
            if label not in labels:
                labels.add(label)
                handles.append(Line2D([], [], color=colour, marker=">", label=label))

    centre = 0.5 * (cloud.min(axis=0) + cloud.max(axis=0))
    half = 0.55 * float(np.max(np.ptp(cloud, axis=0))) or 0.5
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))
    if gravity is not None and np.asarray(gravity, dtype=float)[2] > 0:
        ax.invert_zaxis()  # gravity down on the page
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.legend(handles=handles, loc="upper left", fontsize=8)
    if shown is None:
        title = (title + "\n" if title else "") + "no step converged: undeformed shape only"
    if title:
        ax.set_title(title)
    return fig
