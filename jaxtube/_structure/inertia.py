"""Inertia numbers of a structure that the static model does not need (issue 37).

The tubes' membrane mass per unit length is :attr:`Tube.mass_per_length` (it also carries
their weight); lumped masses are :class:`jaxtube.PointMass`. What only the dynamics needs
lives in :class:`InertiaParameters`, a leaf of :class:`StructureParameters` whose defaults
leave every static caller unchanged.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
from jax import Array

#: Specific gas constant of dry air [J/(kg K)].
AIR_GAS_CONSTANT = 287.05
#: Standard atmospheric pressure [Pa].
STANDARD_ATMOSPHERE = 101325.0


def air_density(gauge_pressure, temperature=288.15, ambient_pressure=STANDARD_ATMOSPHERE):
    """Density of the air inside a tube [kg/m^3] from the ideal gas law,
    ``rho = (p_ambient + p) / (R T)``; ``gauge_pressure`` [Pa] (any shape), ``temperature``
    [K], ``ambient_pressure`` [Pa]."""
    return (ambient_pressure + jnp.asarray(gauge_pressure, float)) / (
        AIR_GAS_CONSTANT * jnp.asarray(temperature, float))


class InertiaParameters(eqx.Module):
    """Inertia numbers only the dynamics uses (every one a differentiable leaf).

    Attributes:
        enclosed_air_density: density of the air inside each tube [kg/m^3], scalar or
            ``[T]``: it adds ``rho pi r^2`` per unit length to a segment's translational and
            bending inertia (not to its axial spin: inviscid air does not turn with the
            membrane). Default 0 (left out); :func:`air_density` gives it from the pressure.
        added_mass_density: ``C_a rho_ambient`` [kg/m^3], scalar or ``[T]``: the
            surrounding air moving with a tube adds ``C_a rho pi r^2`` per unit length to
            its transverse (not axial) inertia (potential flow round a cylinder: ``C_a = 1``;
            Newman 1977, *Marine Hydrodynamics*, section 4.13). Default 0.
        line_mass: mass of each line [kg], scalar or ``[L]``, lumped half to each end.
            Default 0.
        spin_mass_per_length: mass per unit length [kg/m], scalar or ``[T]``, that turns
            with a tube about its own axis and does nothing else: it adds ``mu_s r^2`` per
            unit length to a segment's axial (spin) inertia only, no weight and no
            translational or bending inertia. For a model whose tubes' mass sits on their
            nodes as point masses (the kite_fem import): those carry the tube's weight and
            its translational and bending inertia, but masses on the axis cannot carry its
            spin. Default 0.
    """

    enclosed_air_density: Array = eqx.field(default_factory=lambda: jnp.zeros(()))
    added_mass_density: Array = eqx.field(default_factory=lambda: jnp.zeros(()))
    line_mass: Array = eqx.field(default_factory=lambda: jnp.zeros(()))
    spin_mass_per_length: Array = eqx.field(default_factory=lambda: jnp.zeros(()))
