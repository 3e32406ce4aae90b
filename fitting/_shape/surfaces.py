"""Model surfaces to compare measured markers with: tube axes with radii, and canopy triangles.

A solved structure's tubes are described as axis segments between nodes, each with its
local radius (constant or tapered linearly from ``node_1`` to ``node_2``), grouped by the
tube they belong to (``LE``, ``strut0``, ...). The canopy, when given, is a set of
triangles between nodes. Node positions are an array leaf, so every distance below is
differentiable with respect to them (:meth:`TubeSurfaces.with_positions` puts a deformed
state in).

Geometry (closed forms, no iteration):

- point to axis segment ``a -> b``: the projection parameter
  ``t = clip((p - a).(b - a) / |b - a|^2, 0, 1)``, the axis distance ``|p - a - t (b - a)|``,
  and the local radius ``r(t) = r_1 + t (r_2 - r_1)``;
- point to triangle: the distance to the plane where the projection falls inside the
  triangle (all barycentric coordinates >= 0), otherwise the least distance to its three
  edges (the nearest point of a triangle lies on an edge whenever it is not interior).
"""

from __future__ import annotations

from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array


class TubeSurfaces(eqx.Module):
    """The tube surfaces (and optionally the canopy) of a structure in one state.

    Attributes:
        node_positions: ``[n, 3]`` node positions [m].
        segment_nodes: ``[s, 2]`` the two nodes of each axis segment.
        segment_group: ``[s]`` index into ``group_names`` of each segment's tube.
        radius_start: ``[s]`` tube radius [m] at ``segment_nodes[:, 0]``.
        radius_end: ``[s]`` tube radius [m] at ``segment_nodes[:, 1]``.
        canopy_triangles: ``[t, 3]`` canopy triangles (node numbers); ``t`` may be 0.
        group_names: the tube groups (static).
    """

    node_positions: Array
    segment_nodes: Array
    segment_group: Array
    radius_start: Array
    radius_end: Array
    canopy_triangles: Array
    group_names: tuple[str, ...] = eqx.field(static=True)

    @classmethod
    def from_segments(cls, node_positions, segments: Sequence[tuple],
                      canopy_triangles=None) -> TubeSurfaces:
        """Surfaces from ``(group, node_1, node_2, radius_1 [m], radius_2 [m])`` rows (the
        form :func:`fitting.load_tubes` returns); groups keep their first-seen order."""
        positions = np.asarray(node_positions, float)
        if positions.ndim != 2 or positions.shape[1] != 3 or not np.isfinite(positions).all():
            raise ValueError(f"node_positions must be a finite [n, 3] array, got shape "
                             f"{positions.shape}")
        if len(segments) == 0:
            raise ValueError("no tube segments given")
        names = tuple(dict.fromkeys(str(s[0]) for s in segments))
        nodes = np.asarray([(int(s[1]), int(s[2])) for s in segments], int)
        radii = np.asarray([(float(s[3]), float(s[4])) for s in segments], float)
        bad = np.flatnonzero((nodes < 0).any(1) | (nodes >= len(positions)).any(1))
        if bad.size:
            raise ValueError(f"segment {bad[0]} ({segments[bad[0]]}) names a node outside "
                             f"0..{len(positions) - 1}")
        short = np.flatnonzero(np.linalg.norm(positions[nodes[:, 1]] - positions[nodes[:, 0]],
                                              axis=1) == 0)
        if short.size:
            raise ValueError(f"segment {short[0]} ({segments[short[0]]}) has zero length: its "
                             f"two nodes are at the same position")
        if not (np.isfinite(radii).all() and (radii >= 0).all()):
            raise ValueError("tube radii must be finite and >= 0")
        triangles = np.zeros((0, 3), int) if canopy_triangles is None else \
            np.asarray(canopy_triangles, int).reshape(-1, 3)
        if triangles.size and (triangles.min() < 0 or triangles.max() >= len(positions)):
            raise ValueError(f"a canopy triangle names a node outside 0..{len(positions) - 1}")
        group = np.asarray([names.index(str(s[0])) for s in segments], int)
        return cls(jnp.asarray(positions), jnp.asarray(nodes), jnp.asarray(group),
                   jnp.asarray(radii[:, 0]), jnp.asarray(radii[:, 1]), jnp.asarray(triangles),
                   names)

    def with_positions(self, node_positions) -> TubeSurfaces:
        """The same tubes with other node positions ``[n, 3]`` [m] (a deformed state)."""
        node_positions = jnp.asarray(node_positions)
        if node_positions.shape != self.node_positions.shape:
            raise ValueError(f"expected node positions of shape {self.node_positions.shape}, "
                             f"got {node_positions.shape}")
        return eqx.tree_at(lambda s: s.node_positions, self, node_positions)

    @property
    def has_canopy(self) -> bool:
        return self.canopy_triangles.shape[0] > 0


def tube_surface_distance(surfaces: TubeSurfaces, points: Array,
                          point_group: Array) -> tuple[Array, Array, Array]:
    """Distance from each point to the surface of its group's tube.

    The point is matched by projection: the nearest axis segment of its group is found
    (least distance to the axis), and the distance is that axis distance minus the local
    radius at the projection (positive outside the tube, negative inside).

    Args:
        surfaces: the model's tubes.
        points: ``[m, 3]`` positions [m] in the model frame.
        point_group: ``[m]`` index into ``surfaces.group_names`` of each point's tube.

    Returns:
        ``(distance [m] [m], segment [m], t [m])``: the signed surface distance, the
        nearest segment and the projection parameter on it.
    """
    # The nearest segment is piecewise constant in the positions: found without gradients
    # (over all segments), then the distance is recomputed on that segment alone, which
    # carries the derivatives at O(m) cost.
    frozen = jax.lax.stop_gradient((surfaces.node_positions, points))
    start = frozen[0][surfaces.segment_nodes[:, 0]]                         # [s, 3]
    axis = frozen[0][surfaces.segment_nodes[:, 1]] - start                  # [s, 3]
    offset = frozen[1][:, None, :] - start[None]                            # [m, s, 3]
    t = jnp.clip(jnp.sum(offset * axis, -1) / jnp.sum(axis * axis, -1), 0.0, 1.0)
    gap = offset - t[..., None] * axis
    own_group = point_group[:, None] == surfaces.segment_group[None, :]
    segment = jnp.argmin(jnp.where(own_group, jnp.sum(gap * gap, -1), jnp.inf), axis=1)
    start = surfaces.node_positions[surfaces.segment_nodes[segment, 0]]     # [m, 3]
    axis = surfaces.node_positions[surfaces.segment_nodes[segment, 1]] - start
    offset = points - start
    t_nearest = jnp.clip(jnp.sum(offset * axis, -1) / jnp.sum(axis * axis, -1), 0.0, 1.0)
    gap = offset - t_nearest[:, None] * axis
    axis_distance = jnp.sqrt(jnp.sum(gap * gap, -1))
    radius = surfaces.radius_start[segment] + t_nearest * (
        surfaces.radius_end[segment] - surfaces.radius_start[segment])
    return axis_distance - radius, segment, t_nearest


def _segment_distance(points: Array, a: Array, b: Array) -> Array:
    """``[m, t]`` distance from each point ``[m, 3]`` to each segment ``a, b [t, 3]``."""
    axis = b - a
    offset = points[:, None, :] - a[None]
    t = jnp.clip(jnp.sum(offset * axis, -1) / jnp.sum(axis * axis, -1), 0.0, 1.0)
    gap = offset - t[..., None] * axis
    return jnp.sqrt(jnp.sum(gap * gap, -1) + 1e-30)


def canopy_distance(surfaces: TubeSurfaces, points: Array) -> Array:
    """``[m]`` unsigned distance [m] from each point ``[m, 3]`` to the nearest canopy
    triangle (the canopy is a membrane: no thickness)."""
    corners = surfaces.node_positions[surfaces.canopy_triangles]            # [t, 3, 3]
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    normal = jnp.cross(b - a, c - a)
    area2 = jnp.sum(normal * normal, -1)                                     # [t]
    offset = points[:, None, :] - a[None]                                    # [m, t, 3]
    height = jnp.sum(offset * normal, -1) / area2                            # [m, t]
    foot = offset - height[..., None] * normal                               # relative to a
    # Barycentric coordinates of the foot from the areas of its sub-triangles.
    weight_a = jnp.sum(jnp.cross((b - a) - foot, (c - a) - foot) * normal, -1) / area2
    weight_b = jnp.sum(jnp.cross((c - a) - foot, -foot) * normal, -1) / area2
    inside = (weight_a >= 0) & (weight_b >= 0) & (1 - weight_a - weight_b >= 0)
    plane = jnp.abs(height) * jnp.sqrt(area2)
    edges = jnp.minimum(jnp.minimum(_segment_distance(points, a, b),
                                    _segment_distance(points, b, c)),
                        _segment_distance(points, c, a))
    return jnp.min(jnp.where(inside, plane, edges), axis=1)
