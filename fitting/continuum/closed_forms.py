"""Closed forms: the elastica tip (Mattiasson 1981), Fichter's shear stiffness, the
Comer-Levy collapse load, and the tension-field cantilever built from them.
"""

from __future__ import annotations

import math

from scipy import optimize, special

from .cantilever import CantileverModel
from .laws import tension_field_law
from .scalar import _EPS, BAR

# ---------------------------------------------------------------------------------------
# Closed-form elastica, docs/physics.md, section 4.1


def elastica_tip(alpha: float) -> tuple[float, float, float]:
    """Tip of the inextensible elastica cantilever under a dead vertical tip load.

    Elliptic-integral solution (Mattiasson 1981; docs/physics.md, section 4.1), scipy parameter
    ``m = k^2 = (1 + sin theta0) / 2``, ``sin phi1 = 1 / (k sqrt 2)``::

        sqrt(alpha) = K(m) - F(phi1, m)                    fixes theta0
        v / L       = 1 - (2 / sqrt(alpha)) (E(m) - E(phi1, m))
        u / L       = 1 - sqrt(2 sin(theta0) / alpha)

    Args:
        alpha: load parameter ``P L^2 / EI`` (dimensionless, > 0).

    Returns:
        ``(tip_angle [rad], v / L, u / L)``: tip rotation, vertical deflection and
        horizontal shortening.
    """
    if not alpha > 0.0:
        raise ValueError(f"alpha must be > 0, got {alpha}")

    def parts(theta0):
        m = 0.5 * (1.0 + math.sin(theta0))
        phi1 = math.asin(min(1.0, 1.0 / math.sqrt(2.0 * m)))
        return m, phi1

    def residual(theta0):
        m, phi1 = parts(theta0)
        return special.ellipk(m) - special.ellipkinc(phi1, m) - math.sqrt(alpha)

    # residual -> -sqrt(alpha) as theta0 -> 0 and -> +inf as theta0 -> pi/2.
    theta0 = optimize.brentq(residual, 1e-300, 0.5 * math.pi - 1e-15, xtol=1e-300, rtol=4 * _EPS)
    m, phi1 = parts(theta0)
    v = 1.0 - 2.0 / math.sqrt(alpha) * float(special.ellipe(m) - special.ellipeinc(phi1, m))
    u = 1.0 - math.sqrt(2.0 * math.sin(theta0) / alpha)
    return float(theta0), v, u



# ---------------------------------------------------------------------------------------
# Convenience constructors for the inflated-tube cantilever


def fichter_shear_stiffness(
    pressure: float, radius: float, shear_modulus: float, shear_factor: float = 0.5
) -> float:
    """Fichter shear stiffness ``S = p pi r^2 + k G t 2 pi r`` [N].

    Args:
        pressure: p [Pa]; radius: r [m]; shear_modulus: G t [N/m]; shear_factor: k
            (about 0.5 for a thin tube; docs/physics.md, section 2.4).
    """
    return pressure * math.pi * radius**2 + shear_factor * shear_modulus * 2.0 * math.pi * radius


def comer_levy_collapse_load(pressure: float, radius: float, length: float) -> float:
    """Small-deflection collapse tip load ``M_c / L = pi p r^3 / L`` [N] (Comer & Levy)."""
    return math.pi * pressure * radius**3 / length


def tension_field_cantilever(
    pressure_bar: float,
    radius: float,
    length: float,
    wall_modulus: float,
    shear_modulus: float | None = None,
    shear_factor: float = 0.5,
    **effects,
) -> CantileverModel:
    """A tension-field tube cantilever, with Fichter shear when ``shear_modulus`` (G t
    [N/m]) is given. ``pressure_bar`` in bar, the rest SI; ``effects`` are further
    :class:`CantileverModel` fields (clamp, reinforcement, self-weight)."""
    pressure = pressure_bar * BAR
    shear = (
        None
        if shear_modulus is None
        else fichter_shear_stiffness(pressure, radius, shear_modulus, shear_factor)
    )
    return CantileverModel(
        length=length,
        law=tension_field_law(pressure, radius, wall_modulus),
        shear_stiffness=shear,
        **effects,
    )


