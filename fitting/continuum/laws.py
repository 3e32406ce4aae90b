"""Bending laws of the continuum reference solver: moment and its inverse, curvature.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
from scipy import optimize

from .scalar import (
    _EPS,
    _check_tube,
    _elementwise,
    _tension_field_curvature_scalar,
    _tension_field_moment_scalar,
    tension_field_curvature,
    tension_field_moment,
)

# ---------------------------------------------------------------------------------------
# Laws as pairs of callables


@dataclasses.dataclass(frozen=True)
class BendingLaw:
    """A monotone, point-symmetric moment-curvature law and its inverse.

    Attributes:
        moment: ``M(kappa)``, curvature [1/m] -> moment [N m]; must accept a Python float
            (and should accept arrays).
        curvature: ``kappa(M)``, the inverse; ``+-inf`` at or beyond ``moment_limit``.
        moment_limit: supremum of ``|M|`` [N m] (``inf`` for an unbounded law).
        name: label for messages.

    Any pair of callables can be passed directly; use :func:`law_from_moment` when only
    ``M(kappa)`` is known.
    """

    moment: Callable
    curvature: Callable
    moment_limit: float = math.inf
    name: str = "custom"


def linear_law(bending_stiffness: float) -> BendingLaw:
    """Linear law ``M = EI kappa`` with ``EI`` = ``bending_stiffness`` [N m^2]."""
    if not bending_stiffness > 0.0:
        raise ValueError(f"bending_stiffness must be > 0 [N m^2], got {bending_stiffness}")
    stiffness = float(bending_stiffness)

    def moment(curvature):
        if isinstance(curvature, float):
            return stiffness * curvature
        return stiffness * np.asarray(curvature, dtype=float)

    def curvature(moment):
        if isinstance(moment, float):
            return moment / stiffness
        return np.asarray(moment, dtype=float) / stiffness

    return BendingLaw(moment=moment, curvature=curvature, name=f"linear(EI={stiffness:g})")


def tension_field_law(pressure: float, radius: float, wall_modulus: float) -> BendingLaw:
    """Tension-field tube law (docs/physics.md, section 2.3) for p [Pa], r [m], E t [N/m]."""
    _check_tube(pressure, radius, wall_modulus)
    parameters = (float(pressure), float(radius), float(wall_modulus))

    def moment(curvature):
        if isinstance(curvature, float):  # fast path for the ODE right-hand side
            return _tension_field_moment_scalar(curvature, *parameters)
        return tension_field_moment(curvature, *parameters)

    def curvature(moment):
        if isinstance(moment, float):
            return _tension_field_curvature_scalar(moment, *parameters)
        return tension_field_curvature(moment, *parameters)

    return BendingLaw(
        moment=moment,
        curvature=curvature,
        moment_limit=math.pi * pressure * radius**3,
        name=f"tension-field(p={pressure:g} Pa, r={radius:g} m, Et={wall_modulus:g} N/m)",
    )


def _invert_monotone(moment_fn, moment: float, upper_bound: float | None, scale: float) -> float:
    """Curvature ``kappa >= 0`` with ``moment_fn(kappa) = |moment|``, sign restored."""
    magnitude = abs(moment)
    if magnitude == 0.0 or math.isnan(magnitude):
        return moment if math.isnan(magnitude) else 0.0
    hi = upper_bound if upper_bound is not None else scale
    while float(moment_fn(hi)) < magnitude:
        hi *= 2.0
        if hi > 1e300:
            return math.copysign(math.inf, moment)
    kappa = optimize.brentq(
        lambda k: float(moment_fn(k)) - magnitude, 0.0, hi, xtol=1e-300, rtol=4 * _EPS
    )
    return math.copysign(kappa, moment)


def law_from_moment(
    moment: Callable,
    moment_limit: float = math.inf,
    curvature_scale: float = 1.0,
    name: str = "numerical",
) -> BendingLaw:
    """A law given as ``M(kappa)`` only (odd, strictly increasing); inverted by Brent.

    Args:
        moment: ``M(kappa)`` [N m] for curvature [1/m]; called with Python floats.
        moment_limit: supremum of ``|M|`` [N m]; beyond it the curvature is ``+-inf``.
        curvature_scale: a typical curvature [1/m], the first upper bracket (it doubles
            until it brackets the root).
    """

    def curvature_scalar(m: float) -> float:
        if abs(m) >= moment_limit:
            return math.copysign(math.inf, m)
        return _invert_monotone(moment, m, None, curvature_scale)

    return BendingLaw(
        moment=moment,
        curvature=lambda m: _elementwise(curvature_scalar, m),
        moment_limit=moment_limit,
        name=name,
    )


def reinforced_law(law: BendingLaw, reinforcement_stiffness: float) -> BendingLaw:
    """``M(kappa) = M_law(kappa) + EI_r kappa``: a pressure-independent stiffness in parallel.

    ``EI_r`` = ``reinforcement_stiffness`` [N m^2] (tape, seams, bladder; docs/physics.md,
    section 5.2). The inverse is bracketed by ``0 <= kappa <= min(|M| / EI_r, kappa_law(|M|))``
    and found by Brent's method.
    """
    if reinforcement_stiffness == 0.0:
        return law
    if not reinforcement_stiffness > 0.0:
        raise ValueError(f"reinforcement_stiffness must be >= 0, got {reinforcement_stiffness}")
    stiffness = float(reinforcement_stiffness)

    def moment_scalar(kappa: float) -> float:
        return float(law.moment(kappa)) + stiffness * kappa

    def curvature_scalar(m: float) -> float:
        upper = abs(m) / stiffness
        law_kappa = abs(float(law.curvature(abs(m))))
        if law_kappa < upper:
            upper = law_kappa
        if upper == 0.0:
            return 0.0 * m
        return _invert_monotone(moment_scalar, m, upper, upper)

    return BendingLaw(
        moment=lambda kappa: _elementwise(moment_scalar, kappa),
        curvature=lambda m: _elementwise(curvature_scalar, m),
        moment_limit=math.inf,
        name=f"{law.name} + EI_r={stiffness:g}",
    )


