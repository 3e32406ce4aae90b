"""Mass and rotational inertia of a structure, and its kinetic energy in maximal coordinates.

Each rigid segment of length ``L`` and mean radius ``r`` carries, per unit length, its
membrane mass ``mu_m`` (:attr:`Tube.mass_per_length`, a thin-walled tube), the enclosed air
``mu_a = rho_in pi r^2`` and, for transverse motion only, the added mass of the surrounding
air ``mu_x = C_a rho pi r^2`` (:class:`jaxtube.InertiaParameters`). About its centroid, in
its material frame (third axis along the tube):

    m       = (mu_m + mu_a) L                       translation, every direction
    m_x     = mu_x L                                translation across the axis only
    J_axial = (mu_m + mu_s) L r^2                   thin-walled ring; the air does not spin
    J_trans = mu_m L (r^2/2 + L^2/12) + mu_a L (r^2/4 + L^2/12) + mu_x L^3/12

(the ``r^2`` terms are the section's rotary inertia, the ``L^2/12`` terms the segment's
length; Gere & Goodno, *Mechanics of Materials*, appendix E); ``mu_s`` is the spin-only
mass per length (:attr:`InertiaParameters.spin_mass_per_length`) of a tube whose mass is
lumped on its nodes. Point masses sit on point
unknowns; a line's mass is lumped half to each end.

The kinetic energy is that of the *maximal coordinates* (segment centroids, segment frames,
point positions): ``T = sum m |v_c|^2 / 2 + Omega . J Omega / 2 + sum m_p |v_p|^2 / 2``
with ``Omega`` the body angular velocity (``Q^T dQ/dt = [Omega]x``). The integrator
(:mod:`.integrator`) works with these directly; the modal analysis (:mod:`.modes`) pulls
them back to the solver's state by the velocity map :func:`velocity_map`.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.flatten_util import ravel_pytree

from .._mechanics.geometry import ReferenceGeometry
from .._mechanics.kinematics import positions_from_steps, segment_steps
from .._rotation import matmul3, rotation_vector, transpose3
from .._structure.structure import Structure, StructureParameters


class MassProperties(eqx.Module):
    """Inertia of the maximal coordinates.

    Attributes:
        segment_mass: ``[S]`` [kg], every direction.
        segment_added_mass: ``[S]`` [kg], across the segment's axis only.
        segment_inertia: ``[S, 3]`` [kg m^2], principal moments about the centroid in the
            material frame (``d1``, ``d2``, axis).
        point_mass: ``[P]`` [kg] on the rows of ``state["point_position"]``.
    """

    segment_mass: Array
    segment_added_mass: Array
    segment_inertia: Array
    point_mass: Array


class MaximalCoordinates(eqx.Module):
    """Where the mass is: centroids ``[S, 3]`` [m], frames ``[S, 3, 3]``, points ``[P, 3]``
    [m]."""

    centroid: Array
    frame: Array
    point: Array


def mass_properties(structure: Structure, params: StructureParameters,
                    geometry: ReferenceGeometry | None) -> MassProperties:
    """The segments' and points' inertia from the parameters (module docstring)."""
    inertia = params.inertia
    count = structure.segment_count
    if count:
        a = np.array([n[0] for n in structure.segment_nodes], dtype=np.int32)
        b = np.array([n[1] for n in structure.segment_nodes], dtype=np.int32)
        tube = np.array(structure.segment_tube, dtype=np.int32)
        tubes = len(structure.tube_names)
        radius = 0.5 * (params.node_radius[a] + params.node_radius[b])
        length = geometry.length
        area = jnp.pi * radius**2
        membrane = params.mass_per_length[tube]
        air = jnp.broadcast_to(inertia.enclosed_air_density, (tubes,))[tube] * area
        added = jnp.broadcast_to(inertia.added_mass_density, (tubes,))[tube] * area
        slender = length**2 / 12.0
        transverse = (membrane * (radius**2 / 2 + slender) + air * (radius**2 / 4 + slender)
                      + added * slender) * length
        spin = jnp.broadcast_to(inertia.spin_mass_per_length, (tubes,))[tube]
        axial = (membrane + spin) * radius**2 * length
        segment_mass = (membrane + air) * length
        segment_added = added * length
        segment_inertia = jnp.stack([transverse, transverse, axial], axis=-1)
    else:
        segment_mass = segment_added = jnp.zeros((0,))
        segment_inertia = jnp.zeros((0, 3))
    topology = structure.elements
    point_mass = jnp.zeros((topology.unknown_count,))
    if topology.mass_points:
        point_mass = point_mass.at[np.array(topology.mass_points, np.int32)].add(
            params.elements.point_mass)
    if topology.line_ends:
        ends = np.asarray(topology.line_ends, dtype=np.int32)
        half = 0.5 * jnp.broadcast_to(inertia.line_mass, (len(ends),))
        point_mass = point_mass.at[ends[:, 0]].add(half).at[ends[:, 1]].add(half)
    return MassProperties(segment_mass=segment_mass, segment_added_mass=segment_added,
                          segment_inertia=segment_inertia, point_mass=point_mass)


def maximal_coordinates(structure: Structure, geometry: ReferenceGeometry | None,
                        state: dict) -> MaximalCoordinates:
    """Centroids, frames and point positions of a state."""
    if structure.segment_count:
        frame, step = segment_steps(geometry, state)
        start, end, _ = positions_from_steps(structure, state["root_position"], step)
        centroid = 0.5 * (start + end)
    else:
        frame, centroid = jnp.zeros((0, 3, 3)), jnp.zeros((0, 3))
    point = state["point_position"] if structure.elements.active else jnp.zeros((0, 3))
    return MaximalCoordinates(centroid=centroid, frame=frame, point=point)


def translational_mass(mass: MassProperties, frame: Array) -> Array:
    """Each segment's 3 x 3 translational mass in the world ``m I + m_x (I - a a^T)``
    (``a`` the axis, the frame's third column), ``[S, 3, 3]`` [kg]."""
    axis = frame[..., :, 2]
    eye = jnp.eye(3)
    across = eye - axis[..., :, None] * axis[..., None, :]
    return mass.segment_mass[:, None, None] * eye + mass.segment_added_mass[:, None, None] * across


def velocity_map(structure: Structure, geometry: ReferenceGeometry | None,
                 state: dict) -> Array:
    """``W [3S + 3S + 3P, n]``: centroid velocities, body angular velocities and point
    velocities per unit rate of the flattened state (the kinetic energy is
    ``zdot^T W^T D W zdot / 2`` with ``D`` the maximal coordinates' mass)."""
    z, unravel = ravel_pytree(state)
    here = maximal_coordinates(structure, geometry, state)

    def moved(dz):
        there = maximal_coordinates(structure, geometry, unravel(z + dz))
        turn = rotation_vector(matmul3(transpose3(here.frame), there.frame))
        return jnp.concatenate([there.centroid.reshape(-1), turn.reshape(-1),
                                there.point.reshape(-1)])

    return jax.jacfwd(moved)(jnp.zeros_like(z))


def mass_matrix(structure: Structure, params: StructureParameters,
                geometry: ReferenceGeometry | None, state: dict) -> Array:
    """Mass matrix of the flattened state ``M = W^T D W`` ``[n, n]`` [kg, kg m, kg m^2]
    (:func:`velocity_map`)."""
    mass = mass_properties(structure, params, geometry)
    here = maximal_coordinates(structure, geometry, state)
    w = velocity_map(structure, geometry, state)
    s, p = structure.segment_count, structure.elements.unknown_count
    n = w.shape[1]
    translation = w[: 3 * s].reshape(s, 3, n)
    rotation = w[3 * s: 6 * s].reshape(s, 3, n)
    points = w[6 * s:].reshape(p, 3, n)
    weighted = jnp.einsum("sij,sjn->sin", translational_mass(mass, here.frame), translation)
    matrix = jnp.einsum("sim,sin->mn", translation, weighted)
    matrix = matrix + jnp.einsum("sim,si,sin->mn", rotation, mass.segment_inertia, rotation)
    return matrix + jnp.einsum("pim,p,pin->mn", points, mass.point_mass, points)
