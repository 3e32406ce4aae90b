"""Moment-curvature laws of one tube section component (bending or torsion), per unit length.

Every law maps a curvature `kappa` [1/m] (or a rate of twist, for torsion) of one joint to a
moment `M` [N m], and gives the matching energy density `W` [J/m = N] with `dW/dkappa = M`.
The laws are odd and monotone, so `W` is even and convex (docs/physics.md, section 1.4). They are
`equinox.Module`s; every number is a traced field, so calibration can differentiate with
respect to it. All methods are elementwise and broadcast over `curvature`, `pressure`
(envelope overpressure [Pa]) and `radius` [m]; pressure and radius must be positive.

`energy_density` takes the squared curvature `s = kappa^2` [1/m^2] so that the engine can feed
it `kappa_1^2 + kappa_2^2` (bending from the magnitude of the bending vector, docs/physics.md,
section 1.3) and take `jax.hessian` with respect to `(kappa_1, kappa_2)`. Each law is written to
give a finite and exact gradient and Hessian there, also at exactly zero curvature: near zero
the energies are polynomials in `s` (or safe-`where` guarded), never `sqrt(s)` of a zero.

Sources:

- `SplineLaw`: Breukels & Ockels, AIAA SDM 2008 (three-regime spline through pivots that
  scale as `A (p r^3)^B`); interpolation by monotone piecewise-cubic Hermite slopes of
  Fritsch & Butland (1984), in the weighted harmonic-mean form of Moler's `pchip`.
- `TensionFieldLaw`: no-compression membrane tube in pure bending (docs/physics.md, section 2.3;
  Comer & Levy 1963 for `M_w = pi p r^3 / 2` and `M_c = pi p r^3`); the energy density is
  derived here (see the class docstring).
- `EmpiricalBendingLaw2011`, `EmpiricalTorsionLaw2011`: Breukels, PhD thesis, TU Delft 2011,
  the cantilever fits quoted in docs/physics.md, section 3.

Precision: the laws run in the dtype of their inputs and are written for float64 (which
importing `jaxtube` turns on); they stay finite in float32. This module itself never changes
the global JAX configuration.
"""

from .base import AbstractMomentLaw as AbstractMomentLaw
from .empirical import EmpiricalBendingLaw2011 as EmpiricalBendingLaw2011
from .empirical import EmpiricalTorsionLaw2011 as EmpiricalTorsionLaw2011
from .linear import LinearLaw as LinearLaw
from .linear import ReinforcedLaw as ReinforcedLaw
from .scaled import CurvatureScaledLaw as CurvatureScaledLaw
from .scaled import ScaledLaw as ScaledLaw
from .spline import SplineLaw as SplineLaw
from .tension_field import TensionFieldLaw as TensionFieldLaw
