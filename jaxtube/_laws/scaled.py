"""A moment law scaled by a constant factor: the whole moment-curvature curve times ``s``
(:class:`ScaledLaw`), or stretched along the curvature axis (:class:`CurvatureScaledLaw`).

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


class CurvatureScaledLaw(AbstractMomentLaw):
    """``M = M_base(factor * kappa)``: the base curve stretched along the curvature axis.

    The initial bending stiffness is ``factor`` times the base law's, while the moments the
    curve reaches (the wrinkling moment, the collapse plateau: for an inflated tube set by
    ``p r^3``) stay the base law's, reached at curvatures ``1 / factor`` times larger. The
    alternative to :class:`ScaledLaw` (which scales stiffness and strength alike) when a
    tube is softer than its law but not weaker: the fabric, seams or bladder add compliance,
    while the membrane's wrinkling and collapse are governed by pressure and radius
    (Comer & Levy 1963; docs/physics.md). Energy: ``W(kappa) = W_base(factor kappa) /
    factor``, so ``dW/dkappa = M``; the regime is the base law's at ``factor * kappa``.

    Fields: ``base`` (any law), ``factor`` (dimensionless, > 0; a leaf, fittable).
    """

    base: AbstractMomentLaw
    factor: Array = eqx.field(converter=as_float)

    def energy_density(self, curvature_sq, pressure, radius):
        return self.base.energy_density(self.factor**2 * curvature_sq, pressure,
                                        radius) / self.factor

    def moment(self, curvature, pressure, radius):
        return self.base.moment(self.factor * curvature, pressure, radius)

    def regime(self, curvature, pressure, radius):
        return self.base.regime(self.factor * curvature, pressure, radius)

    def initial_stiffness(self, pressure, radius):
        return self.factor * self.base.initial_stiffness(pressure, radius)
