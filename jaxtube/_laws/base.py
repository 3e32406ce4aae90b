"""The interface of every moment-curvature law, and the helpers the laws share.

Conventions (the package docstring of :mod:`jaxtube._laws` has the whole story): curvature
[1/m], pressure = envelope overpressure [Pa], radius [m], moment [N m], energy density
[J/m = N], stiffness [N m^2]. Laws are odd and monotone, so the energy density is even and
convex (docs/physics.md, section 1.4).
"""

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

Array = jax.Array

# Regime thresholds shared by the smooth laws, as fractions of their limiting moment: a
# section counts as wrinkled from half the limit moment (Comer & Levy: M_w = M_c / 2) and as
# collapsed from 95 % of it.
WRINKLED_MOMENT_FRACTION = 0.5
COLLAPSED_MOMENT_FRACTION = 0.95


# --------------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------------


def as_float(x: ArrayLike) -> Array:
    """`x` as a JAX array of a floating dtype (integers go to the default float dtype)."""
    x = jnp.asarray(x)
    if not jnp.issubdtype(x.dtype, jnp.inexact):
        x = x.astype(float)
    return x


def as_optional_float(x: ArrayLike | None) -> Array | None:
    return None if x is None else as_float(x)


def magnitude_from_square(curvature_sq: Array) -> Array:
    """`sqrt(s)` for `s >= 0`, with a finite derivative (taken as 0) at exactly `s = 0`.

    The inner `where` keeps the unused `sqrt` branch away from 0 so that reverse- and
    forward-mode derivatives never form `0 * inf`. Use it only inside expressions whose true
    derivative at zero does not depend on `d sqrt(s) / ds` (odd powers multiplied by `s`).
    """
    positive = curvature_sq > 0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, curvature_sq, 1.0)), 0.0)


def polynomial(z: Array, coefficients: tuple[float, ...]) -> Array:
    """`sum_n coefficients[n] z^n` by Horner's rule."""
    result = jnp.full_like(z, coefficients[-1])
    for coefficient in reversed(coefficients[:-1]):
        result = result * z + coefficient
    return result


def concrete_or_none(x: Array) -> np.ndarray | None:
    """The value of `x` as numpy if it is concrete, `None` if it is traced."""
    try:
        return np.asarray(x)
    except (jax.errors.TracerArrayConversionError, jax.errors.ConcretizationTypeError):
        return None


# --------------------------------------------------------------------------------------------
# The interface
# --------------------------------------------------------------------------------------------


class AbstractMomentLaw(eqx.Module):
    """Odd, monotone moment-curvature law of one section component (bending or torsion), per
    unit length.

    Arguments of every method are arrays of any mutually broadcastable shapes; results have
    the broadcast shape. Units: curvature [1/m], pressure = envelope overpressure [Pa],
    radius [m], moment [N m], energy density [J/m = N], stiffness [N m^2].
    """

    @abc.abstractmethod
    def energy_density(self, curvature_sq: ArrayLike, pressure: ArrayLike,
                       radius: ArrayLike) -> Array:
        """Energy density `W(kappa)` [N] with `W(0) = 0`, as a function of `kappa^2` [1/m^2].

        Gradient and Hessian with respect to a curvature vector `(kappa_1, kappa_2)` through
        `curvature_sq = kappa_1^2 + kappa_2^2` are finite and exact, also at exactly zero.
        """

    @abc.abstractmethod
    def moment(self, curvature: ArrayLike, pressure: ArrayLike, radius: ArrayLike) -> Array:
        """Moment `M = dW/dkappa` [N m]; odd and non-decreasing in `curvature` [1/m]."""

    @abc.abstractmethod
    def regime(self, curvature: ArrayLike, pressure: ArrayLike, radius: ArrayLike) -> Array:
        """int32 regime of `|curvature|`: 0 unwrinkled, 1 wrinkled, 2 collapsed."""

    @abc.abstractmethod
    def initial_stiffness(self, pressure: ArrayLike, radius: ArrayLike) -> Array:
        """`dM/dkappa` at zero curvature [N m^2]."""
