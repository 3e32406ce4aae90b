"""A moment law scaled by a constant factor: the whole moment-curvature curve times ``s``.

Kite codes that use Breukels' 2011 law on full kites find it too stiff and scale the whole
tube curve: Billow's best V3 shapes need ``s = 0.36``, kite_fem's beams end near ``0.23``
(``experiments/data/v3_hanging/README.md``). ``M_s(kappa) = s M(kappa)``, so ``W_s = s W``;
the regime boundaries are the base law's, at the same curvatures.
"""

from __future__ import annotations

import equinox as eqx
from jax import Array

from .base import AbstractMomentLaw, as_float


class ScaledLaw(AbstractMomentLaw):
    """``M = factor * M_base(kappa)`` for any base law (energy, moment and initial stiffness
    scaled alike; the regime is the base law's).

    Fields: ``base`` (any law), ``factor`` (dimensionless, > 0; a leaf, so it can be fitted
    by gradient).
    """

    base: AbstractMomentLaw
    factor: Array = eqx.field(converter=as_float)

    def energy_density(self, curvature_sq, pressure, radius):
        return self.factor * self.base.energy_density(curvature_sq, pressure, radius)

    def moment(self, curvature, pressure, radius):
        return self.factor * self.base.moment(curvature, pressure, radius)

    def regime(self, curvature, pressure, radius):
        return self.base.regime(curvature, pressure, radius)

    def initial_stiffness(self, pressure, radius):
        return self.factor * self.base.initial_stiffness(pressure, radius)
