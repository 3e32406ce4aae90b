"""3-D figure of registered markers on a model's tubes, coloured by their surface distance."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from .score import ShapeScore
from .surfaces import TubeSurfaces


def draw_shape(axes, score: ShapeScore, surfaces: TubeSurfaces, title: str, limit_mm: float):
    """Tube axes (grey, width ~ radius) and markers (|distance| [mm], shared colour limit)
    on 3-D ``axes``; returns the scatter for a colour bar."""
    positions = np.asarray(surfaces.node_positions)
    nodes = np.asarray(surfaces.segment_nodes)
    radius = np.asarray(surfaces.radius_start + surfaces.radius_end) / 2
    for (a, b), r in zip(nodes, radius):
        axes.plot(*positions[[a, b]].T, color="0.45", lw=1 + 40 * r, alpha=0.6,
                  solid_capstyle="round")
    if surfaces.has_canopy:
        for triangle in np.asarray(surfaces.canopy_triangles):
            axes.plot(*positions[np.r_[triangle, triangle[0]]].T, color="0.85", lw=0.3)
    points = score.registered_m
    canopy = np.asarray([g == "canopy" for g in score.model_group])
    error = np.abs(score.distance_mm)
    scatter = axes.scatter(*points[~canopy].T, c=error[~canopy], cmap="viridis", vmin=0,
                           vmax=limit_mm, s=22, depthshade=False, label="tube markers")
    if canopy.any() and surfaces.has_canopy:
        axes.scatter(*points[canopy].T, c=error[canopy], cmap="viridis", vmin=0,
                     vmax=limit_mm, marker="^", s=26, depthshade=False, label="canopy markers")
    elif canopy.any():
        axes.scatter(*points[canopy].T, color="0.6", marker="^", s=26, depthshade=False,
                     label="canopy markers (not scored: no canopy)")
    span = np.ptp(np.vstack([positions[nodes.reshape(-1)], points]), axis=0).max() / 2
    centre = positions[nodes.reshape(-1)].mean(0)
    for setter, c in zip((axes.set_xlim, axes.set_ylim, axes.set_zlim), centre):
        setter(c - span, c + span)
    axes.set_xlabel("x [m]")
    axes.set_ylabel("y [m]")
    axes.set_zlabel("z [m]")
    axes.set_title(f"{title}\nRMS {score.rms_mm:.0f} mm (tube markers)"
                   + (f", canopy {score.canopy_rms_mm:.0f} mm"
                      if score.canopy_rms_mm is not None else ""), fontsize=9)
    axes.legend(loc="upper left", fontsize=7)
    return scatter


def shape_figure(score: ShapeScore, surfaces: TubeSurfaces, path, *, null: ShapeScore = None,
                 undeformed: TubeSurfaces = None) -> None:
    """Write the figure (one panel, or two with the undeformed null model) to ``path``."""
    panels = [(score, surfaces, "model")]
    if null is not None:
        panels.append((null, undeformed, "undeformed (null model)"))
    errors = np.concatenate([np.abs(s.distance_mm[np.isfinite(s.distance_mm)])
                             for s, _, _ in panels])
    limit = float(np.percentile(errors, 95)) if errors.size else 1.0
    figure = Figure(figsize=(6.5 * len(panels), 6))
    for k, (s, surface, title) in enumerate(panels):
        axes = figure.add_subplot(1, len(panels), k + 1, projection="3d")
        scatter = draw_shape(axes, s, surface, title, limit)
    figure.colorbar(scatter, ax=figure.axes, shrink=0.6,
                    label="|distance to tube surface| [mm]")
    figure.savefig(path, dpi=110)
