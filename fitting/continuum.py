"""Independent continuum reference: a planar large-deflection cantilever in numpy/scipy.

This module does **not** import jaxtube. It solves the same physical problem as the
rigid-segment engine by a different route (a continuum beam integrated by a high-order
ODE solver), so that agreement between the two is evidence and not an echo. It also makes
synthetic "measured" force-deflection curves for testing the fitting and diagnosis code.

Moment-curvature laws (all SI: curvature in 1/m, moment in N m)
----------------------------------------------------------------
A law is a monotone, point-symmetric pair ``moment(curvature)`` / ``curvature(moment)``
(:class:`BendingLaw`). Provided:

- :func:`linear_law`: ``M = EI kappa``.
- :func:`tension_field_law` (no-compression membrane tube, docs/physics.md, section 2.3, after
  Comer & Levy 1963): ``EI = pi Et r^3`` up to ``kappa_w = p / (2 Et)``; beyond, with ``a``
  the half-angle of the taut arc (pi down to 0)::

      kappa(a) = pi p / (2 Et (sin a - a cos a))
      M(a)     = (pi p r^3 / 2) (a - sin a cos a) / (sin a - a cos a)

  so ``M_w = pi p r^3 / 2`` at onset and ``M -> M_c = pi p r^3`` as ``kappa -> inf``. The
  plain functions :func:`tension_field_moment` and :func:`tension_field_curvature` invert the
  parametric form for ``a`` (safeguarded Newton, small-``a`` Taylor series to avoid the
  cancellation in ``sin a - a cos a``), to about 1e-13 relative.
- :func:`law_from_moment`: any monotone ``M(kappa)``; its inverse is found numerically.
- :func:`reinforced_law`: ``M(kappa) + EI_r kappa`` (pressure-independent reinforcement).

Cantilever model (:class:`CantileverModel`)
-------------------------------------------
A horizontal beam of length ``L``, clamped at the root ``s = 0``, dead vertical tip load
``P`` (downward positive), optional self-weight ``w g`` per unit length (dead load along the
deformed centreline). Frame: ``x`` along the undeformed axis from the root, ``y``
**downward**; ``theta(s)`` is the rotation of the cross-section, positive when the section
turns downward (clockwise in a y-up picture). Inextensible Reissner kinematics with the
Fichter shear strain ``gamma``::

    dx/ds     = cos(theta) - gamma sin(theta)
    dy/ds     = sin(theta) + gamma cos(theta)
    dtheta/ds = kappa(M(s))          (M = M_law(kappa) + EI_r kappa)
    dM/ds     = -V(s) dx/ds,         V(s) = P + w g (L - s)

``V(s)`` is the downward resultant of all loads beyond ``s`` (inextensible, so the weight
beyond ``s`` is ``w g (L - s)`` whatever the shape) and ``M(s)`` their moment about the
centreline point at ``s`` (positive when it bends the tube downward). Shear (Fichter 1966;
Le van & Wielgosz 2005, docs/physics.md, section 2.4) uses the resultant's component *perpendicular
to the deformed section*, ``V_perp = V cos(theta)`` (the component ``V sin(theta)`` along
the section normal is axial force and does not shear)::

    gamma = V cos(theta) / S,        S = p pi r^2 + k G t 2 pi r    [N]

Boundary conditions: at the root ``x = y = 0`` and the section rotation is the clamp
rotation ``theta(0) = M(0) / k_clamp`` (zero for a rigid clamp); at the free end
``M(L) = 0``.

Solution method. Because the tube is inextensible, ``V(s)`` is known in closed form for
any shape, so the equations can be integrated from the root to the tip with
:func:`scipy.integrate.solve_ivp` (DOP853, rtol 1e-10) from a trial *root curvature*
``kappa_0`` (``M(0) = M(kappa_0)``); the moment of the weight on the deformed part beyond
``s`` is carried by ``dM/ds = -V dx/ds`` (equivalent to a tip-to-root integration with
``(x, y, theta, M, V)``). Shooting on ``M(L) = 0``, which increases monotonically with
``kappa_0``, is done by Brent's method on a doubling bracket. Shooting on the root
curvature rather than the tip angle keeps every trial finite and well-conditioned on a
collapse plateau: a tip-angle trial runs into ``M >= M_c`` (infinite curvature) whenever
the load is too large for it, while a root-curvature trial only ever sees ``|M| <= M(0)``
until it turns past vertical, which flags it as run-away.

Displacement control (:meth:`CantileverModel.tip_force`, :meth:`CantileverModel.curve`)
solves for ``(kappa_0, P)`` together: continuation in the deflection from the unloaded
state (secant predictor, Broyden-updated Newton corrector with step halving; unknowns
``asinh(kappa_0 / kappa_s)`` and ``P / P_s``), adaptive step, and Brent on the load as a
last resort. This follows the curve wherever it is monotone, including the collapse
plateau of a softening law.

The tip deflection is measured from the *unloaded* shape (``P = 0``, which sags under
self-weight), as a bench test zeroes its gauge.

Closed form (:func:`elastica_tip`): the elliptic-integral elastica of a cantilever with a
dead tip load (Mattiasson 1981; docs/physics.md, section 4.1).

Sources: docs/physics.md, sections 2 and 4; Comer & Levy, AIAA J. 1 (1963) (wrinkling and
collapse moments); Fichter, NASA technical note (1966), and Le van & Wielgosz,
Thin-Walled Struct. 43 (2005) (pressure term in the shear stiffness); Mattiasson, Int. J.
Numer. Meth. Eng. 17 (1981) (elliptic-integral elastica); Reissner, ZAMP 23 (1972) (planar
shear-deformable finite-strain beam kinematics).
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import math
from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np
from scipy import optimize, special
from scipy.integrate import solve_ivp

GRAVITY = 9.81  # m/s^2
BAR = 1.0e5  # Pa

# Curvatures beyond this [x 1/L] are capped: only run-away trials get there.
_RUNAWAY_CURVATURE = 1.0e8
# Displacement control gives up beyond this many force scales (0.01 EI / L^2 for a linear law).
_MAX_LOAD_FACTOR = 1.0e8
_SERIES_TERMS = 12
_RUNAWAY_ANGLE = 0.5 * math.pi + 0.25
_RUNAWAY_RESIDUAL = 1.0e3  # residual reported for a run-away shot (asinh never gets there)
_EPS = np.finfo(float).eps

__all__ = [
    "BAR",
    "GRAVITY",
    "BendingLaw",
    "CantileverModel",
    "CantileverShape",
    "CurveSpec",
    "DeflectionOutOfReach",
    "comer_levy_collapse_load",
    "elastica_tip",
    "fichter_shear_stiffness",
    "law_from_moment",
    "linear_law",
    "make_dataset",
    "prescribed_deflections",
    "reinforced_law",
    "tension_field_cantilever",
    "tension_field_curvature",
    "tension_field_law",
    "tension_field_moment",
]


# ---------------------------------------------------------------------------------------
# Element-wise helpers


def _elementwise(scalar_fn: Callable[[float], float], values):
    """Apply a scalar function element-wise; a scalar in gives a Python float out."""
    array = np.asarray(values, dtype=float)
    if array.ndim == 0:
        return scalar_fn(float(array))
    flat = [scalar_fn(float(v)) for v in array.ravel()]
    return np.asarray(flat, dtype=float).reshape(array.shape)


def _safeguarded_newton(fun, target: float, lo: float, hi: float, x0: float) -> float:
    """Root of the increasing function ``fun(x) - target`` on ``[lo, hi]``.

    ``fun`` returns ``(value, derivative)``. Newton steps that leave the bracket are
    replaced by bisection; stops at machine precision in ``x``.
    """
    x = min(max(x0, lo), hi)
    for _ in range(100):
        value, slope = fun(x)
        residual = value - target
        if residual == 0.0:
            return x
        if residual > 0.0:
            hi = x
        else:
            lo = x
        step = residual / slope if slope > 0.0 else math.inf
        x_new = x - step
        if not (lo < x_new < hi):
            x_new = 0.5 * (lo + hi)
        if abs(x_new - x) <= 2.0 * _EPS * abs(x) or hi - lo <= 2.0 * _EPS * abs(x):
            return x_new
        x = x_new
    return x


# ---------------------------------------------------------------------------------------
# Tension-field (no-compression) tube law, docs/physics.md, section 2.3


def _taut_arc_functions(a: float) -> tuple[float, float, float]:
    """``f = sin a - a cos a``, ``w = 2 f - (a - sin a cos a)`` and ``a - sin a``.

    Taylor series below a = 1 (the closed forms cancel catastrophically as a -> 0):
    ``f = sum (-1)^(n+1) 2n a^(2n+1)/(2n+1)!``, ``a - sin a cos a = sum (-1)^(n+1) 4^n
    a^(2n+1)/(2n+1)!``, ``a - sin a = sum (-1)^(n+1) a^(2n+1)/(2n+1)!`` (n >= 1).
    """
    if a < 1.0:
        a2 = a * a
        term = a
        f = w = a_minus_sin = 0.0
        sign = 1.0
        for n in range(1, _SERIES_TERMS + 1):
            term *= a2 / ((2 * n) * (2 * n + 1))
            f += sign * (2 * n) * term
            w += sign * (4 * n - 4**n) * term
            a_minus_sin += sign * term
            sign = -sign
        return f, w, a_minus_sin
    sin_a, cos_a = math.sin(a), math.cos(a)
    f = sin_a - a * cos_a
    return f, 2.0 * f - (a - sin_a * cos_a), a - sin_a


def _check_tube(pressure: float, radius: float, wall_modulus: float) -> None:
    if not (pressure > 0.0 and radius > 0.0 and wall_modulus > 0.0):
        raise ValueError(
            "tension-field law needs pressure > 0 [Pa], radius > 0 [m] and "
            f"wall_modulus (E t) > 0 [N/m]; got {pressure}, {radius}, {wall_modulus}"
        )


def _tension_field_moment_scalar(curvature: float, pressure, radius, wall_modulus) -> float:
    magnitude = abs(curvature)
    if math.isnan(magnitude):
        return math.nan
    onset_curvature = pressure / (2.0 * wall_modulus)
    stiffness = math.pi * wall_modulus * radius**3
    if magnitude <= onset_curvature:
        return stiffness * curvature
    collapse_moment = math.pi * pressure * radius**3
    if math.isinf(magnitude):
        return math.copysign(collapse_moment, curvature)
    # Solve f(a) = pi kappa_w / kappa for the taut half-angle a (f increasing on [0, pi]).
    target = math.pi * onset_curvature / magnitude

    def f_and_slope(a):
        f, _, _ = _taut_arc_functions(a)
        return f, a * math.sin(a)

    guess = min((3.0 * target) ** (1.0 / 3.0), math.pi - math.sqrt(2.0 * (1.0 - target / math.pi)))
    a = _safeguarded_newton(f_and_slope, target, 0.0, math.pi, guess)
    f, w, _ = _taut_arc_functions(a)
    # M = M_w (a - sin a cos a) / f = M_c (1 - w / (2 f)).
    return math.copysign(collapse_moment * (1.0 - w / (2.0 * f)), curvature)


def _tension_field_curvature_scalar(moment: float, pressure, radius, wall_modulus) -> float:
    magnitude = abs(moment)
    if math.isnan(magnitude):
        return math.nan
    stiffness = math.pi * wall_modulus * radius**3
    collapse_moment = math.pi * pressure * radius**3
    if magnitude <= 0.5 * collapse_moment:
        return moment / stiffness
    if magnitude >= collapse_moment:
        return math.copysign(math.inf, moment)
    onset_curvature = pressure / (2.0 * wall_modulus)
    # Solve q(a) = w / (2 f) = 1 - M / M_c (q increasing from 0 at a=0 to 1/2 at a=pi).
    target = 1.0 - magnitude / collapse_moment

    def q_and_slope(a):
        f, w, a_minus_sin = _taut_arc_functions(a)
        sin_a = math.sin(a)
        df = a * sin_a
        dw = 2.0 * sin_a * a_minus_sin
        return w / (2.0 * f), (dw * f - w * df) / (2.0 * f * f)

    guess = min(math.sqrt(10.0 * target), math.pi - 2.0 * math.sqrt(max(0.5 - target, 0.0)))
    a = _safeguarded_newton(q_and_slope, target, 0.0, math.pi, guess)
    f, _, _ = _taut_arc_functions(a)
    return math.copysign(math.pi * onset_curvature / f, moment)


def tension_field_moment(curvature, pressure: float, radius: float, wall_modulus: float):
    """Bending moment [N m] of a no-compression (tension-field) tube at a curvature [1/m].

    Args:
        curvature: scalar or array of any shape [1/m]; the law is odd in it.
        pressure: overpressure p [Pa].
        radius: tube radius r [m].
        wall_modulus: membrane stiffness E t [N/m].

    Returns:
        Moment of the same shape (a float for scalar input) [N m]: ``pi Et r^3 kappa`` up
        to ``kappa_w = p/(2 Et)``, then the parametric wrinkled branch of docs/physics.md,
        section 2.3 (``M -> pi p r^3`` as ``kappa -> inf``).
    """
    _check_tube(pressure, radius, wall_modulus)
    return _elementwise(
        lambda k: _tension_field_moment_scalar(k, pressure, radius, wall_modulus), curvature
    )


def tension_field_curvature(moment, pressure: float, radius: float, wall_modulus: float):
    """Inverse of :func:`tension_field_moment`: curvature [1/m] at a moment [N m].

    Valid for ``|M| < M_c = pi p r^3``; returns ``+-inf`` for ``|M| >= M_c`` (the tube has
    collapsed: no finite curvature carries that moment). Scalar or array input; a float for
    scalar input.
    """
    _check_tube(pressure, radius, wall_modulus)
    return _elementwise(
        lambda m: _tension_field_curvature_scalar(m, pressure, radius, wall_modulus), moment
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
# Cantilever model


class DeflectionOutOfReach(ValueError):
    """The requested tip deflection cannot be reached by any tip load of the model."""


class _Shot(NamedTuple):
    """One root-to-tip integration for a trial root curvature and tip load."""

    runaway: int  # 0, or the sign of theta where a section turned past vertical
    x_tip: float  # tip position relative to the root [m]
    y_tip: float  # (y downward)
    tip_angle: float  # [rad]
    tip_moment: float  # bending moment left at the free end [N m]; zero at equilibrium
    remaining: float  # arc length not reached on a run-away [m]
    solution: object  # solve_ivp result (dense output when requested)


@dataclasses.dataclass(frozen=True, eq=False)
class CantileverShape:
    """Equilibrium centreline, root to tip (arrays of shape ``[n]``).

    Attributes:
        arclength: s [m] from the root.
        x: horizontal position [m] from the root.
        y: vertical position [m] from the root, positive downward.
        rotation: section rotation theta [rad], positive downward.
        moment: bending moment [N m] (positive bends the tube downward).
        load: the tip load P [N] (downward positive).
        root_curvature: curvature at the root [1/m].
    """

    arclength: np.ndarray
    x: np.ndarray
    y: np.ndarray
    rotation: np.ndarray
    moment: np.ndarray
    load: float
    root_curvature: float


@dataclasses.dataclass(frozen=True)
class CantileverModel:
    """Planar continuum cantilever with optional shear, clamp compliance, reinforcement and
    self-weight (equations in the module docstring).

    Attributes:
        length: L [m].
        law: bending law of the tube (:class:`BendingLaw`).
        shear_stiffness: Fichter shear stiffness ``S = p pi r^2 + k G t 2 pi r`` [N]
            (see :func:`fichter_shear_stiffness`); None = no shear deformation.
        clamp_stiffness: rotational spring at the root ``k_clamp`` [N m/rad]; root rotation
            ``M_root / k_clamp``; None = rigid clamp.
        reinforcement_stiffness: ``EI_r`` [N m^2] in parallel with the law (0 = none).
        mass_per_length: w [kg/m] for self-weight (0 = weightless).
        tip_mass: a point mass [kg] hanging at the tip (its weight ``tip_mass g`` is a dead
            tip load present before loading, not part of the measured load).
        gravity: g [m/s^2].
        rtol: relative tolerance of the ODE solver; the absolute tolerances are ``rtol``
            times L (positions), 1 rad (angle) and a moment scale.
    """

    length: float
    law: BendingLaw
    shear_stiffness: float | None = None
    clamp_stiffness: float | None = None
    reinforcement_stiffness: float = 0.0
    mass_per_length: float = 0.0
    tip_mass: float = 0.0
    gravity: float = GRAVITY
    rtol: float = 1e-10

    def __post_init__(self):
        if not self.length > 0.0:
            raise ValueError(f"length must be > 0 [m], got {self.length}")
        if self.shear_stiffness is not None and not self.shear_stiffness > 0.0:
            raise ValueError(f"shear_stiffness must be > 0 [N] or None, got {self.shear_stiffness}")
        if self.clamp_stiffness is not None and not self.clamp_stiffness > 0.0:
            raise ValueError(
                f"clamp_stiffness must be > 0 [N m/rad] or None, got {self.clamp_stiffness}"
            )
        if min(self.reinforcement_stiffness, self.mass_per_length, self.tip_mass) < 0.0:
            raise ValueError("reinforcement_stiffness, mass_per_length and tip_mass must be "
                             ">= 0")

    # -- internals ----------------------------------------------------------------------

    @functools.cached_property
    def _bending_law(self) -> BendingLaw:
        return reinforced_law(self.law, self.reinforcement_stiffness)

    @property
    def _weight_per_length(self) -> float:
        return self.mass_per_length * self.gravity  # N/m

    @functools.cached_property
    def _curvature_scale(self) -> float:
        return 0.01 / self.length  # 1/m: a small-deflection curvature

    @functools.cached_property
    def _moment_scale(self) -> float:
        """Moment [N m] at the curvature scale: normalises the tip-moment residual."""
        return abs(float(self._bending_law.moment(self._curvature_scale)))

    @functools.cached_property
    def _force_scale(self) -> float:
        """Tip load [N] that bends the tube to about the curvature scale."""
        return self._moment_scale / self.length

    def _integrate(self, root_curvature: float, load: float, dense: bool = False) -> _Shot:
        """Integrate root (s = 0) to tip (s = L) from a trial root curvature [1/m]."""
        length = self.length
        weight = self._weight_per_length
        tip_load = load + self.tip_mass * self.gravity  # measured load + the hanging mass
        shear = self.shear_stiffness
        law = self._bending_law
        curvature = law.curvature
        limit = law.moment_limit

        def rhs(s, state):
            theta, moment = state[2], state[3]
            resultant = tip_load + weight * (length - s)  # V: downward resultant beyond s
            # Past the moment limit (or at absurd curvature) the trial is running away
            # anyway; a capped curvature lets it turn past vertical in a few steps.
            kappa = float(curvature(float(moment))) if abs(moment) < limit else math.inf
            if not abs(kappa) <= runaway_curvature:
                kappa = math.copysign(runaway_curvature, moment)
            cos_t, sin_t = math.cos(theta), math.sin(theta)
            if shear is None:
                dx, dy = cos_t, sin_t
            else:
                gamma = resultant * cos_t / shear  # V_perp / S
                dx, dy = cos_t - gamma * sin_t, sin_t + gamma * cos_t
            return np.array([dx, dy, kappa, -resultant * dx])

        def turned_past_vertical(s, state):
            # Equilibria under downward dead loads keep |theta| < pi/2; a trial whose
            # section turns past that has far too much (or too little) root curvature.
            return abs(state[2]) - _RUNAWAY_ANGLE

        turned_past_vertical.terminal = True
        runaway_curvature = _RUNAWAY_CURVATURE / length
        if not abs(root_curvature) <= runaway_curvature:
            sign = 1 if root_curvature > 0.0 else -1
            return _Shot(sign, 0.0, 0.0, sign * _RUNAWAY_ANGLE, 0.0, length, None)
        root_moment = float(law.moment(float(root_curvature)))
        root_rotation = 0.0 if self.clamp_stiffness is None else root_moment / self.clamp_stiffness
        moment_scale = max(abs(root_moment), self._moment_scale)
        solution = solve_ivp(
            rhs,
            (0.0, length),
            np.array([0.0, 0.0, root_rotation, root_moment]),
            method="DOP853",
            rtol=self.rtol,
            atol=self.rtol * np.array([length, length, 1.0, moment_scale]),
            events=turned_past_vertical,
            dense_output=dense,
        )
        x, y, theta, moment = solution.y[:, -1]
        runaway = 0 if solution.status == 0 else (1 if theta > 0.0 else -1)
        remaining = length - solution.t[-1] if runaway else 0.0
        return _Shot(runaway, x, y, theta, moment, remaining, solution)

    def _tip_residual(self, shot: _Shot) -> float:
        """``asinh(M(L) / moment scale)``: increasing in the root curvature, zero at
        equilibrium; a run-away trial is placed beyond every regular value on its side."""
        if shot.runaway:
            return shot.runaway * (_RUNAWAY_RESIDUAL + shot.remaining / self.length)
        return math.asinh(shot.tip_moment / self._moment_scale)

    def _shoot(self, load: float) -> tuple[float, _Shot]:
        """Root curvature [1/m] and shot that satisfy ``M(L) = 0`` under tip load ``load``."""

        def residual(root_curvature):
            return self._tip_residual(self._integrate(root_curvature, load))

        at_zero = residual(0.0)
        if at_zero == 0.0:
            return 0.0, self._integrate(0.0, load)
        sign = 1.0 if at_zero < 0.0 else -1.0  # the way the root curvature must go
        # First upper bracket: the curvature of the small-deflection root moment, which
        # large deflections only reduce (shorter lever arms).
        law = self._bending_law
        root_moment = (abs(load + self.tip_mass * self.gravity) * self.length
                       + 0.5 * self._weight_per_length * self.length**2)
        root_moment = min(root_moment, (1.0 - 1e-6) * law.moment_limit)
        first = abs(float(law.curvature(root_moment)))
        lo, hi = 0.0, sign * (first if first > 0.0 else self._curvature_scale)
        while sign * residual(hi) < 0.0:
            lo, hi = hi, 2.0 * hi
            if abs(hi) > 1e300:
                raise RuntimeError(f"shooting failed for tip load {load} N ({self.law.name})")
        root_curvature = optimize.brentq(residual, lo, hi, xtol=1e-300, rtol=4 * _EPS)
        shot = self._integrate(root_curvature, load)
        if shot.runaway:
            raise RuntimeError(f"shooting failed for tip load {load} N ({self.law.name})")
        return root_curvature, shot

    @functools.cached_property
    def _unloaded(self) -> tuple[float, float]:
        """Root curvature [1/m] and tip sag [m] of the unloaded shape (self-weight and tip
        mass only)."""
        if self._weight_per_length == 0.0 and self.tip_mass == 0.0:
            return 0.0, 0.0
        root_curvature, shot = self._shoot(0.0)
        return root_curvature, shot.y_tip

    # -- force control ------------------------------------------------------------------

    def tip_position(self, load: float) -> tuple[float, float]:
        """Tip position ``(x, y)`` [m] relative to the root, y positive downward, under a
        dead tip load ``load`` [N] (downward positive)."""
        _, shot = self._shoot(float(load))
        return float(shot.x_tip), float(shot.y_tip)

    def tip_deflection(self, load: float) -> float:
        """Vertical tip displacement [m], positive downward, from the unloaded shape."""
        return self.tip_position(load)[1] - self._unloaded[1]

    def shape(self, load: float, num_points: int = 101) -> CantileverShape:
        """Equilibrium centreline under tip load ``load`` [N], ``num_points`` points."""
        root_curvature, _ = self._shoot(float(load))
        full = self._integrate(root_curvature, float(load), dense=True)
        arclength = np.linspace(0.0, self.length, num_points)
        x, y, theta, moment = full.solution.sol(arclength)
        return CantileverShape(arclength, x, y, theta, moment, float(load), root_curvature)

    # -- displacement control -----------------------------------------------------------
    #
    # Unknowns are scaled: ``u = asinh(kappa_0 / kappa_scale)`` (log-like on a collapse
    # plateau, where the root curvature grows fast) and ``p = load / force_scale``.

    def _to_physical(self, unknowns) -> tuple[float, float]:
        return (
            self._curvature_scale * math.sinh(unknowns[0]),
            float(unknowns[1]) * self._force_scale,
        )

    def _displacement_residual(self, unknowns, target: float) -> np.ndarray:
        """``[asinh(M(L) / M_scale), (deflection - target) / L]``."""
        root_curvature, load = self._to_physical(unknowns)
        shot = self._integrate(root_curvature, load)
        if shot.runaway:
            return np.array([self._tip_residual(shot), float(shot.runaway)])
        deflection = shot.y_tip - self._unloaded[1]
        return np.array([self._tip_residual(shot), (deflection - target) / self.length])

    def _newton_force(self, target: float, guess, jacobian=None):
        """Scaled unknowns for a ``target`` deflection [m], by Broyden-updated Newton.

        Starts from ``guess`` (scaled unknowns) and ``jacobian`` (e.g. from the previous
        point of a curve; else by forward differences). A step that does not reduce the
        max-norm residual first refreshes the Jacobian, then is halved. The load is kept on
        the side of the target. Returns ``(unknowns, jacobian)``, or None when it does not
        converge (callers then take smaller continuation steps, or bracket).
        """
        direction = 1.0 if target > 0.0 else -1.0

        def admissible(u):
            return np.array([u[0], direction * max(direction * u[1], 0.0)])

        def finite_difference_jacobian(u, residual):
            columns = []
            for j in range(2):
                shifted = u.copy()
                shifted[j] += 1e-7 * max(abs(u[j]), 1e-2)
                columns.append(
                    (self._displacement_residual(shifted, target) - residual) / (shifted[j] - u[j])
                )
            return np.column_stack(columns)

        unknowns = admissible(np.asarray(guess, dtype=float))
        residual = self._displacement_residual(unknowns, target)
        if jacobian is None:
            jacobian, fresh = finite_difference_jacobian(unknowns, residual), True
        else:
            fresh = False
        for _ in range(12):
            norm = float(np.max(np.abs(residual)))
            if norm < 1e-12:
                break
            try:
                step = np.linalg.solve(jacobian, -residual)
            except np.linalg.LinAlgError:
                step = None
            damping, trial = 1.0, None
            while step is not None and damping >= 1.0 / 16.0:
                candidate = admissible(unknowns + damping * step)
                candidate_residual = self._displacement_residual(candidate, target)
                if float(np.max(np.abs(candidate_residual))) < norm:
                    trial, trial_residual = candidate, candidate_residual
                    break
                if not fresh:
                    break  # an old Jacobian: refresh it before damping
                damping *= 0.5
            if trial is None:
                if fresh:
                    break  # no descent with an exact Jacobian: noise floor, or lost
                jacobian, fresh = finite_difference_jacobian(unknowns, residual), True
                continue
            change = trial - unknowns
            # Broyden's ("good") rank-one update.
            jacobian = jacobian + np.outer(
                trial_residual - residual - jacobian @ change, change
            ) / float(change @ change)
            fresh = False
            unknowns, residual = trial, trial_residual
            if np.all(np.abs(change) <= 1e-13 * (1.0 + np.abs(unknowns))):
                break
        if not float(np.max(np.abs(residual))) < 1e-9:
            return None
        return unknowns, jacobian

    def _continue(self, target: float, history: list, jacobian=None):
        """Follow the equilibrium path from ``history[-1]`` to the deflection ``target``.

        ``history`` holds ``(deflection [m], scaled unknowns)`` of solved points on one side
        of zero, starting with the unloaded state. Predictor: linear extrapolation of the
        physical root curvature and the load through the last two points (from the unloaded
        state alone, the small-load response); extrapolating ``asinh`` linearly would
        overshoot wildly. Corrector: :meth:`_newton_force`. A failed corrector halves the
        step, a success doubles it. Solved points are appended to ``history``. Returns
        ``(unknowns, jacobian)`` at ``target``, or None.
        """
        kappa_scale = self._curvature_scale
        step = target - history[-1][0]
        while abs(step) > 1e-6 * abs(target):
            last, unknowns = history[-1]
            next_deflection = target if abs(target - last) <= abs(step) else last + step
            curvature = kappa_scale * math.sinh(unknowns[0])
            if len(history) >= 2:
                previous_deflection, previous = history[-2]
                run = last - previous_deflection
                curvature_rate = (curvature - kappa_scale * math.sinh(previous[0])) / run
                load_rate = (unknowns[1] - previous[1]) / run
            else:
                compliance, curvature_per_load = self._linear_response
                curvature_rate = curvature_per_load / compliance
                load_rate = 1.0 / (compliance * self._force_scale)
            increment = next_deflection - last
            guess = np.array(
                [
                    math.asinh((curvature + increment * curvature_rate) / kappa_scale),
                    unknowns[1] + increment * load_rate,
                ]
            )
            solved = self._newton_force(next_deflection, guess, jacobian)
            if solved is None:
                step *= 0.5
                jacobian = None
                continue
            unknowns, jacobian = solved
            history.append((next_deflection, unknowns))
            if next_deflection == target:
                return unknowns, jacobian
            step *= 2.0
        return None

    def _unloaded_history(self) -> list:
        """``[(0, scaled unknowns of the unloaded state)]``: where continuation starts."""
        return [(0.0, np.array([math.asinh(self._unloaded[0] / self._curvature_scale), 0.0]))]

    def _bracketed_force(self, target: float) -> float:
        """Robust fallback: Brent on the load, each evaluation a full shooting solve.

        The load doubles from the force scale until the deflection passes the target; it
        gives up at ``_MAX_LOAD_FACTOR`` force scales.
        """

        def excess(load):
            return self.tip_deflection(load) - target

        direction = 1.0 if target >= 0.0 else -1.0
        lo, hi = 0.0, direction * self._force_scale
        while abs(hi) <= _MAX_LOAD_FACTOR * self._force_scale:
            try:
                value = excess(hi)
            except RuntimeError:
                break
            if direction * value >= 0.0:
                return optimize.brentq(excess, lo, hi, xtol=1e-14 * abs(hi), rtol=4 * _EPS)
            lo, hi = hi, 2.0 * hi
        raise DeflectionOutOfReach(
            f"tip deflection {target:.6g} m not reached by the model ({self.law.name}, "
            f"L={self.length} m): the largest load solved, {lo:.4g} N, gives "
            f"{self.tip_deflection(lo):.6g} m. Either the deflection is beyond the model's "
            "reach, or the tube would hang so nearly vertical that shooting is "
            "ill-conditioned (load parameter P L^2 / EI above about 1000)."
        )

    @functools.cached_property
    def _linear_response(self) -> tuple[float, float]:
        """Small-load tip compliance [m/N] and root-curvature sensitivity [1/(m N)]."""
        load = 1e-3 * self._force_scale
        root_curvature, shot = self._shoot(load)
        return (
            (shot.y_tip - self._unloaded[1]) / load,
            (root_curvature - self._unloaded[0]) / load,
        )

    def _check_reach(self, target: float) -> None:
        if self.shear_stiffness is None:
            # Inextensible: the tip stays within L of the root.
            sag = self._unloaded[1]
            reach = self.length - sag if target > 0.0 else self.length + sag
            if abs(target) >= reach:
                raise DeflectionOutOfReach(
                    f"tip deflection {target} m is beyond the reach ({reach:.6g} m) of an "
                    f"inextensible tube of length {self.length} m"
                )

    def _solve_deflection(self, target: float, history: list, jacobian=None):
        """``(load [N], jacobian)`` at deflection ``target`` [m]: continuation along
        ``history`` (see :meth:`_continue`), else Brent on the load."""
        if target == 0.0:
            return 0.0, jacobian
        self._check_reach(target)
        solved = self._continue(target, history, jacobian)
        if solved is not None:
            return self._to_physical(solved[0])[1], solved[1]
        load = self._bracketed_force(target)
        root_curvature = self._shoot(load)[0]
        unknowns = np.array(
            [math.asinh(root_curvature / self._curvature_scale), load / self._force_scale]
        )
        history.append((target, unknowns))
        return load, None

    def tip_force(self, deflection: float) -> float:
        """Dead tip load [N] that gives the tip deflection ``deflection`` [m] (displacement
        control; positive downward, measured from the unloaded shape).

        Works wherever the force-deflection curve is monotone, including the collapse
        plateau of a softening law (continuation from the unloaded state with adaptive
        steps, then a bracketing fallback).

        Raises:
            DeflectionOutOfReach: no tip load (up to ``_MAX_LOAD_FACTOR`` force scales)
                reaches that deflection.
        """
        return self._solve_deflection(float(deflection), self._unloaded_history())[0]

    def curve(self, deflections) -> np.ndarray:
        """Tip loads [N] at tip deflections [m] (array of any shape and order).

        Solved in order of increasing ``|deflection|`` on each side of zero by
        continuation (secant predictor, Broyden corrector reusing the Jacobian), so a
        curve costs a few ODE solves per point.
        """
        deflections = np.asarray(deflections, dtype=float)
        flat = deflections.reshape(-1)
        forces = np.zeros(flat.shape)
        for positive in (True, False):
            history, jacobian = self._unloaded_history(), None
            for i in np.argsort(np.abs(flat)):
                target = float(flat[i])
                if target != 0.0 and (target > 0.0) == positive:
                    forces[i], jacobian = self._solve_deflection(target, history, jacobian)
        return forces.reshape(deflections.shape)


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


# ---------------------------------------------------------------------------------------
# Synthetic datasets


@dataclasses.dataclass(frozen=True)
class CurveSpec:
    """One synthetic curve: a model evaluated at prescribed deflections.

    Attributes:
        name: the ``curve`` column.
        model: the cantilever model.
        deflections_mm: prescribed (noise-free) tip deflections [mm].
        pressure_bar, radius_m: metadata columns (the model does not read them).
    """

    name: str
    model: CantileverModel
    deflections_mm: Sequence[float]
    pressure_bar: float
    radius_m: float


def prescribed_deflections(
    model: CantileverModel, max_load: float, num_points: int = 25
) -> np.ndarray:
    """``num_points`` evenly spaced deflections [mm] from ``d/num_points`` up to the
    deflection ``d`` at tip load ``max_load`` [N] (e.g. 0.93 x Comer-Levy collapse)."""
    largest = model.tip_deflection(max_load) * 1e3
    return largest * np.arange(1, num_points + 1) / num_points


_COLUMNS = ("curve", "setup", "pressure_bar", "radius_m", "length_m", "deflection_mm", "force_N")


def make_dataset(
    curves: Sequence[CurveSpec],
    noise_force_N: float,
    noise_deflection_mm: float,
    seed: int,
    path=None,
) -> list[dict]:
    """Long-format rows ``curve,setup,pressure_bar,radius_m,length_m,deflection_mm,force_N``.

    Each model is evaluated (displacement control) at its prescribed deflections; then
    independent Gaussian noise of standard deviation ``noise_deflection_mm`` [mm] and
    ``noise_force_N`` [N] is added to the deflection and force columns, as in the shared
    ``cantilever_shear.csv``. Setup is ``cantilever_tip``. Deflections are rounded to
    1 um and forces to 0.1 mN. When ``path`` is given the rows are also written there as
    CSV.
    """
    rng = np.random.default_rng(seed)
    rows = []
    for spec in curves:
        deflections_mm = np.asarray(spec.deflections_mm, dtype=float)
        forces = spec.model.curve(deflections_mm * 1e-3)
        noisy_deflections = deflections_mm + noise_deflection_mm * rng.standard_normal(
            deflections_mm.shape
        )
        noisy_forces = forces + noise_force_N * rng.standard_normal(forces.shape)
        for deflection, force in zip(noisy_deflections, noisy_forces):
            rows.append(
                {
                    "curve": spec.name,
                    "setup": "cantilever_tip",
                    "pressure_bar": spec.pressure_bar,
                    "radius_m": spec.radius_m,
                    "length_m": spec.model.length,
                    "deflection_mm": round(float(deflection), 3),
                    "force_N": round(float(force), 4),
                }
            )
    if path is not None:
        with open(path, "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=_COLUMNS)
            writer.writeheader()
            for row in rows:
                writer.writerow(
                    {
                        **row,
                        "deflection_mm": f"{row['deflection_mm']:.3f}",
                        "force_N": f"{row['force_N']:.4f}",
                    }
                )
    return rows
