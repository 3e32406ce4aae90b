"""A user-defined effect: a point mass hanging at the tip (a load-cell hook, a shackle).

Use it from the command line::

    jaxtube fit DATA.csv --effect experiments/effects/tip_mass.py:TipMass --out out/fit

or from Python: ``fitting.fit(data, effects=(TipMass,))``. Its weight is a dead load at the
tip; the rig zeroes the measured deflection at the unloaded shape, so only the stiffening
(large deflection) and the earlier wrinkling it causes remain visible.
"""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from fitting import Effect, EffectParameter


class TipMass(Effect):
    """A point mass ``mass`` [kg] at the loaded tip, weight ``mass * g`` along gravity."""

    name: ClassVar[str] = "tip_mass"
    parameters: ClassVar[tuple[EffectParameter, ...]] = (
        EffectParameter("mass", "kg", null=0.0, lower=0.0, upper=20.0, typical=0.1),)
    mass: jnp.ndarray = eqx.field(converter=jnp.asarray)

    def apply(self, params, specimen):
        weight = self.mass * jnp.asarray(specimen.gravity)
        force = params.node_force.at[specimen.tip_node].add(weight)
        return eqx.tree_at(lambda p: p.node_force, params, force)
