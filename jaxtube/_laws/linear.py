"""Linear law ``M = EI kappa``, and a pressure-independent stiffness in parallel with any law."""

from typing import final

import equinox as eqx
import jax.numpy as jnp

from .base import AbstractMomentLaw, Array, as_float


@final
class LinearLaw(AbstractMomentLaw):
    """Linear law `M = stiffness * kappa`, `W = stiffness * kappa^2 / 2`; always regime 0.

    `stiffness` [N m^2]: scalar or array broadcasting with the evaluation shape. Pressure and
    radius only take part in broadcasting.
    """

    stiffness: Array = eqx.field(converter=as_float)

    def energy_density(self, curvature_sq, pressure, radius):
        curvature_sq, pressure, radius = jnp.broadcast_arrays(
            as_float(curvature_sq), as_float(pressure), as_float(radius))
        return 0.5 * self.stiffness * curvature_sq

    def moment(self, curvature, pressure, radius):
        curvature, pressure, radius = jnp.broadcast_arrays(
            as_float(curvature), as_float(pressure), as_float(radius))
        return self.stiffness * curvature

    def regime(self, curvature, pressure, radius):
        shape = jnp.broadcast_shapes(jnp.shape(curvature), jnp.shape(pressure),
                                     jnp.shape(radius), jnp.shape(self.stiffness))
        return jnp.zeros(shape, dtype=jnp.int32)

    def initial_stiffness(self, pressure, radius):
        pressure, radius = jnp.broadcast_arrays(as_float(pressure), as_float(radius))
        return self.stiffness * jnp.ones_like(pressure)


class ReinforcedLaw(AbstractMomentLaw):
    """A law with a pressure-independent stiffness in parallel: `M = M_base + EI_r kappa`.

    Models tape, seams or a bladder that carry bending whatever the pressure (docs/physics.md,
    section 5.2: delays wrinkling, lifts the collapse plateau, relatively larger at low
    pressure). The regime is the base law's (the reinforcement does not wrinkle).

    Fields: `base` (any law), `reinforcement_stiffness` EI_r [N m^2] (>= 0).
    """

    base: AbstractMomentLaw
    reinforcement_stiffness: Array = eqx.field(converter=as_float)

    def energy_density(self, curvature_sq, pressure, radius):
        return (self.base.energy_density(curvature_sq, pressure, radius)
                + 0.5 * self.reinforcement_stiffness * as_float(curvature_sq))

    def moment(self, curvature, pressure, radius):
        return (self.base.moment(curvature, pressure, radius)
                + self.reinforcement_stiffness * as_float(curvature))

    def regime(self, curvature, pressure, radius):
        return self.base.regime(curvature, pressure, radius)

    def initial_stiffness(self, pressure, radius):
        return self.base.initial_stiffness(pressure, radius) + self.reinforcement_stiffness
