"""One inflated tube (:class:`Tube`) and the generators of its centreline.

A tube is a discretised centreline with its radius at each node, its overpressure and its
laws; :func:`straight_tube`, :func:`arc_tube` and :func:`polyline_tube` make one from a
line, a circular arc or a polyline, with a constant or tapered radius.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array

from .._laws import AbstractMomentLaw


class Tube(eqx.Module):
    """One inflated tube: a discretised centreline with its section properties and laws.

    Attributes:
        name: unique name, used to refer to nodes as ``"name:index"``.
        nodes: reference centreline nodes, shape ``[n_segments + 1, 3]`` [m].
        radius: tube radius at each node, shape ``[n_segments + 1]`` [m].
        pressure: envelope overpressure [Pa].
        bending_law: moment-curvature law of bending (isotropic in the cross-section).
        torsion_law: moment-twist law of torsion; defaults to the bending law (a thin
            isotropic tube has ``GJ / EI = 1 / (1 + nu)``, so this is a rough default: give
            a torsion law whenever torsion matters).
        mass_per_length: tube mass per unit length [kg/m] (self-weight).
        line_load: uniform dead line load along the tube, world frame, shape ``[3]`` [N/m].
        shear_flexibility: ``None`` (rigid in shear, the default) or ``u = 1 / (2 pi k G t)``
            [m/N] > 0: Fichter-type shear deformation with the section shear stiffness
            ``S = p pi r^2 + k G A = p pi r^2 + r / u`` [N] (``A = 2 pi r t``; Fichter 1966,
            Le van & Wielgosz 2005; docs/physics.md, section 2.4). Every segment then gets a
            transverse shear strain ``gamma [2]`` with energy ``S L |gamma|^2 / 2``.
    """

    name: str = eqx.field(static=True)
    nodes: Array
    radius: Array
    pressure: Array
    bending_law: AbstractMomentLaw
    torsion_law: AbstractMomentLaw
    mass_per_length: Array
    line_load: Array
    shear_flexibility: Array | None

    def __init__(
        self,
        name: str,
        nodes,
        radius,
        pressure,
        bending_law: AbstractMomentLaw,
        torsion_law: AbstractMomentLaw | None = None,
        mass_per_length=0.0,
        line_load=(0.0, 0.0, 0.0),
        shear_flexibility=None,
    ):
        self.name = str(name)
        self.nodes = jnp.asarray(nodes, dtype=float)
        if self.nodes.ndim != 2 or self.nodes.shape[1] != 3 or self.nodes.shape[0] < 2:
            raise ValueError(f"tube {name!r}: nodes must have shape [n_segments + 1 >= 2, 3]")
        radius = jnp.asarray(radius, dtype=float)
        self.radius = jnp.broadcast_to(radius, self.nodes.shape[:1])
        self.pressure = jnp.asarray(pressure, dtype=float)
        self.bending_law = bending_law
        self.torsion_law = torsion_law if torsion_law is not None else bending_law
        self.mass_per_length = jnp.asarray(mass_per_length, dtype=float)
        self.line_load = jnp.asarray(line_load, dtype=float)
        self.shear_flexibility = (None if shear_flexibility is None
                                  else jnp.asarray(shear_flexibility, dtype=float))

    @property
    def n_segments(self) -> int:
        return self.nodes.shape[0] - 1


def _radius_profile(radius, fractions: np.ndarray) -> np.ndarray:
    """Radius at arc-length fractions: a scalar, or ``[(fraction, radius), ...]`` pairs."""
    table = np.asarray(radius, dtype=float)
    if table.ndim == 0:
        return np.full_like(fractions, float(table))
    if table.ndim != 2 or table.shape[1] != 2:
        raise ValueError("radius must be a number or a list of [fraction, radius] pairs")
    return np.interp(fractions, table[:, 0], table[:, 1])


def straight_tube(name, start, end, segments, radius, pressure, bending_law, **kwargs) -> Tube:
    """A straight tube from ``start`` to ``end`` [m] cut into ``segments`` equal segments.

    ``radius`` is a number [m] or ``[(fraction_of_length, radius_m), ...]`` for a taper.
    Remaining keyword arguments go to :class:`Tube`.
    """
    fractions = np.linspace(0.0, 1.0, int(segments) + 1)
    start, end = np.asarray(start, float), np.asarray(end, float)
    nodes = start[None, :] + fractions[:, None] * (end - start)[None, :]
    return Tube(name, nodes, _radius_profile(radius, fractions), pressure, bending_law, **kwargs)


def arc_tube(
    name, centre, arc_radius, start_angle, end_angle, segments, radius, pressure, bending_law,
    normal=(0.0, 0.0, 1.0), reference=(1.0, 0.0, 0.0), **kwargs,
) -> Tube:
    """A circular-arc tube: ``centre + R (cos phi u + sin phi v)``, ``phi`` from start to end.

    ``u`` is ``reference`` made orthogonal to ``normal`` (the arc plane's normal) and
    ``v = normal x u``. Angles in radians, lengths in m.
    """
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    u = np.asarray(reference, float)
    u = u - normal * (u @ normal)
    u = u / np.linalg.norm(u)
    v = np.cross(normal, u)
    fractions = np.linspace(0.0, 1.0, int(segments) + 1)
    phi = start_angle + fractions * (end_angle - start_angle)
    nodes = np.asarray(centre, float)[None, :] + arc_radius * (
        np.cos(phi)[:, None] * u[None, :] + np.sin(phi)[:, None] * v[None, :]
    )
    return Tube(name, nodes, _radius_profile(radius, fractions), pressure, bending_law, **kwargs)


def polyline_tube(name, points, segments, radius, pressure, bending_law, **kwargs) -> Tube:
    """A tube along a polyline through ``points`` [m], resampled at equal arc length."""
    points = np.asarray(points, float)
    lengths = np.linalg.norm(np.diff(points, axis=0), axis=1)
    if np.any(lengths <= 0.0):
        raise ValueError(f"tube {name!r}: polyline has repeated points")
    arc = np.concatenate([[0.0], np.cumsum(lengths)])
    fractions = np.linspace(0.0, 1.0, int(segments) + 1)
    target = fractions * arc[-1]
    nodes = np.stack([np.interp(target, arc, points[:, k]) for k in range(3)], axis=1)
    return Tube(name, nodes, _radius_profile(radius, fractions), pressure, bending_law, **kwargs)
