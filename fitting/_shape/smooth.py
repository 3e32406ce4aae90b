"""The peers' marker metric made differentiable, for fitting by gradient.

The peers' score (:func:`fitting.score_shape`) takes each beam's radius as constant along
the beam, so a marker's surface distance steps where its nearest axis segment changes from
one beam to the next: the score is discontinuous in the node positions, and a gradient
taken at an optimum that sits on such a step is wrong. The smooth variant differs in one
thing: **the radius is continuous along each tube**, each node's radius the mean of the
radii its tube's beams give it, linear along each segment (:func:`continuous_radius`). The
axis distance (the distance to the nearest point of the tube's polyline axis) is
continuous, and differentiable wherever that nearest point is unique (everywhere but on the
axis's medial set, far from the tube's surface), so the surface distance is too.

The registration is the same least-squares solve (:func:`fitting.register`, iterated to a
relative cost change of 1e-14) on the smooth surfaces. At its optimum the gradient of the
RMS with respect to the registration vanishes, so the gradient of

    F(x) = min_g RMS(x, g)

with respect to the node positions is the partial gradient at the optimal ``g`` (envelope
theorem): :func:`smooth_shape_score` returns it, and a gradient with respect to model
parameters is its product with the equilibrium's tangents ``dx/dtheta`` (implicit function
theorem, :meth:`fitting.CaseSolver.tangents`).
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._data.units import MM_PER_M
from .markers import CANOPY_GROUP, MarkerSet
from .registration import Registration, RegistrationResult, marker_rms, register
from .surfaces import TubeSurfaces


def continuous_radius(surfaces: TubeSurfaces) -> TubeSurfaces:
    """``surfaces`` with each tube's radius continuous along it: every node's radius is the
    mean of the radii its group's segments give it there, and each segment tapers linearly
    between its nodes' radii (a constant-radius tube is unchanged)."""
    nodes = np.asarray(surfaces.segment_nodes)
    group = np.asarray(surfaces.segment_group)
    ends = (np.asarray(surfaces.radius_start), np.asarray(surfaces.radius_end))
    total: dict = {}
    count: dict = {}
    for segment, (a, b) in enumerate(nodes.tolist()):
        for node, radius in ((a, ends[0][segment]), (b, ends[1][segment])):
            key = (int(group[segment]), node)
            total[key] = total.get(key, 0.0) + float(radius)
            count[key] = count.get(key, 0) + 1
    mean = {key: total[key] / count[key] for key in total}
    start = [mean[(int(g), a)] for g, (a, _) in zip(group, nodes.tolist())]
    end = [mean[(int(g), b)] for g, (_, b) in zip(group, nodes.tolist())]
    return eqx.tree_at(lambda s: (s.radius_start, s.radius_end), surfaces,
                       (jnp.asarray(start), jnp.asarray(end)))


@dataclasses.dataclass(frozen=True)
class SmoothScore:
    """The smooth metric of one shape (module docstring).

    Attributes:
        rms_mm: RMS [mm] over the tube markers of the surface distance, radius continuous.
        position_gradient: ``[n, 3]`` d RMS [m] / d node positions [m], registration held
            at its optimum.
        registration: the registration on the smooth surfaces.
    """

    rms_mm: float
    position_gradient: np.ndarray
    registration: RegistrationResult


def smooth_shape_score(surfaces: TubeSurfaces, markers: MarkerSet, *, spanwise_groups="auto",
                       canopy_group: str = CANOPY_GROUP,
                       start: Registration | None = None) -> SmoothScore:
    """Register ``markers`` onto ``surfaces`` with continuous radii and return the RMS and
    its gradient with respect to the node positions (module docstring). ``start``: the
    registration of the same markers on a nearby shape, iterated from instead of the search
    (:func:`fitting.register`)."""
    smooth = continuous_radius(surfaces)
    found = register(smooth, markers, spanwise_groups=spanwise_groups,
                     canopy_group=canopy_group, start=start)
    value, gradient = jax.value_and_grad(lambda x: marker_rms(
        smooth.with_positions(x), markers, found.registration))(smooth.node_positions)
    return SmoothScore(float(value) * MM_PER_M, np.asarray(gradient), found)
