"""Fitted coordinates of the spline law's pivot scaling, and the physics-based first guess.

A :class:`jaxtube.SplineLaw` with ``K`` pivots has, per pivot increment ``i`` and per
coordinate (curvature ``kappa`` and moment ``M``):

- ``paper`` form (Breukels & Ockels 2008): ``y_i = A_i (p r^3)^B_i``;
- ``separate`` form: ``y_i = A_i p^B_i r^C_i`` (the paper's form is ``C = 3 B``).

The optimiser does not work on ``A`` directly: ``A`` spans many decades and is strongly
correlated with ``B`` when ``p r^3`` is far from 1. It works on ``log a_i``, the increment
at a reference specimen ``(p_ref, r_ref)`` (the geometric mean of the data), and the
exponents:

- paper: ``y_i = a_i (p r^3 / (p_ref r_ref^3))^B_i``, so ``A_i = a_i (p_ref r_ref^3)^-B_i``;
- separate: ``y_i = a_i (p / p_ref)^B_i (r / r_ref)^C_i``, ``A_i = a_i p_ref^-B_i r_ref^-C_i``.

Both keep the law monotone for every parameter value (the increments are positive).

The first guess (no hand tuning): the initial slope of each measured curve gives the
bending stiffness ``EI = k0 L^3 / 3`` and the wall stiffness ``E t = EI / (pi r^3)``
(``EI = E t pi r^3``, docs/physics.md, section 2.1); the pivots then follow the tension-field tube
with that ``E t``, whose wrinkling and collapse moments are Comer & Levy's
``pi p r^3 / 2`` and ``pi p r^3`` (:meth:`jaxtube.SplineLaw.from_tension_field`).
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

import jaxtube as jt

from .._data import MeasuredData

FORMS = ("paper", "separate")
COORDINATES = ("kappa", "M")


@dataclasses.dataclass(frozen=True)
class PivotScaling:
    """Which spline law is fitted and how its coordinates are laid out.

    Attributes:
        form: ``"paper"`` or ``"separate"``.
        pivots_per_regime: pivots in the unwrinkled, wrinkled and collapsed regimes.
        residual_stiffness_ratio: collapsed-regime slope over the initial slope (fixed).
    """

    form: str = "paper"
    pivots_per_regime: tuple[int, int, int] = (1, 1, 1)
    residual_stiffness_ratio: float = 0.01

    def __post_init__(self):
        if self.form not in FORMS:
            raise ValueError(f"form must be one of {FORMS}, got {self.form!r}")
        counts = tuple(int(n) for n in self.pivots_per_regime)
        if len(counts) != 3 or min(counts) < 1:
            raise ValueError(f"pivots_per_regime must be three integers >= 1, got {counts}")
        object.__setattr__(self, "pivots_per_regime", counts)

    @property
    def pivot_count(self) -> int:
        return sum(self.pivots_per_regime)

    @property
    def exponents(self) -> tuple[str, ...]:
        return ("B",) if self.form == "paper" else ("B", "C")

    def names(self) -> list[str]:
        """Names of the fitted coordinates, in vector order: for each coordinate, ``log a``
        of every pivot, then each exponent of every pivot (``kappa[1].B`` ...)."""
        names = []
        for coordinate in COORDINATES:
            for kind in ("A",) + self.exponents:
                names += [f"{coordinate}[{i + 1}].{kind}" for i in range(self.pivot_count)]
        return names

    def regime_of_pivot(self, index: int) -> int:
        """0, 1 or 2: the regime whose pivots include pivot ``index`` (0-based)."""
        bounds = np.cumsum(self.pivots_per_regime)
        return int(np.searchsorted(bounds, index, side="right"))

    def _split(self, vector):
        k, e = self.pivot_count, 1 + len(self.exponents)
        parts = []
        for c in range(2):
            block = vector[c * k * e:(c + 1) * k * e]
            parts.append([block[j * k:(j + 1) * k] for j in range(e)])
        return parts  # [coordinate][0: log a, 1: B, 2: C]

    def law(self, vector, reference_pressure, reference_radius) -> jt.SplineLaw:
        """The :class:`jaxtube.SplineLaw` of a fitted vector (traceable)."""
        (log_ak, *exp_k), (log_am, *exp_m) = self._split(vector)
        p_ref, r_ref = reference_pressure, reference_radius
        if self.form == "paper":
            s_ref = jnp.log(p_ref * r_ref**3)
            return jt.SplineLaw(
                curvature_scale=jnp.exp(log_ak - exp_k[0] * s_ref),
                curvature_exponent=exp_k[0],
                moment_scale=jnp.exp(log_am - exp_m[0] * s_ref),
                moment_exponent=exp_m[0],
                residual_stiffness_ratio=self.residual_stiffness_ratio,
                pivots_per_regime=self.pivots_per_regime)
        lp, lr = jnp.log(p_ref), jnp.log(r_ref)
        return jt.SplineLaw(
            curvature_scale=jnp.exp(log_ak - exp_k[0] * lp - exp_k[1] * lr),
            curvature_exponent=exp_k[0], curvature_radius_exponent=exp_k[1],
            moment_scale=jnp.exp(log_am - exp_m[0] * lp - exp_m[1] * lr),
            moment_exponent=exp_m[0], moment_radius_exponent=exp_m[1],
            residual_stiffness_ratio=self.residual_stiffness_ratio,
            pivots_per_regime=self.pivots_per_regime)

    def vector(self, law: jt.SplineLaw, reference_pressure, reference_radius) -> np.ndarray:
        """Inverse of :meth:`law` for a law of this form."""
        p_ref, r_ref = float(reference_pressure), float(reference_radius)
        blocks = []
        if self.form == "paper":
            if law.curvature_radius_exponent is not None:
                raise ValueError("a separate-form law cannot be written in the paper form")
            s_ref = np.log(p_ref * r_ref**3)
            for scale, exponent in ((law.curvature_scale, law.curvature_exponent),
                                    (law.moment_scale, law.moment_exponent)):
                b = np.broadcast_to(np.asarray(exponent, float), (self.pivot_count,))
                blocks += [np.log(np.asarray(scale, float)) + b * s_ref, b]
        else:
            lp, lr = np.log(p_ref), np.log(r_ref)
            paper = law.curvature_radius_exponent is None
            for scale, exponent, radius_exponent in (
                    (law.curvature_scale, law.curvature_exponent,
                     law.curvature_radius_exponent),
                    (law.moment_scale, law.moment_exponent, law.moment_radius_exponent)):
                b = np.broadcast_to(np.asarray(exponent, float), (self.pivot_count,))
                c = 3.0 * b if paper else np.asarray(radius_exponent, float)
                blocks += [np.log(np.asarray(scale, float)) + b * lp + c * lr, b, c]
        return np.concatenate(blocks)

    def physical(self, vector, reference_pressure, reference_radius) -> dict[str, float]:
        """``{name: value}`` with ``A`` in SI (N m and 1/m per unit of the scaling variable
        to the power B), exponents as they are."""
        law = self.law(jnp.asarray(vector), reference_pressure, reference_radius)
        values = {}
        for coordinate, scale, exps in (
                ("kappa", law.curvature_scale, (law.curvature_exponent,
                                                law.curvature_radius_exponent)),
                ("M", law.moment_scale, (law.moment_exponent, law.moment_radius_exponent))):
            for i in range(self.pivot_count):
                values[f"{coordinate}[{i + 1}].A"] = float(scale[i])
                for kind, exponent in zip(self.exponents, exps):
                    values[f"{coordinate}[{i + 1}].{kind}"] = float(exponent[i])
        return values


def initial_slope(deflection: np.ndarray, force: np.ndarray) -> float:
    """Least-squares slope through the origin of the points below 35 % of the peak force
    (the unwrinkled part: wrinkling starts near half the collapse load) [N/m]."""
    u, f = np.abs(np.asarray(deflection)), np.abs(np.asarray(force))
    order = np.argsort(u)
    u, f = u[order], f[order]
    keep = f <= 0.35 * f.max()
    if keep.sum() < 2:
        keep = np.arange(u.size) < min(3, u.size)
    return float(np.sum(u[keep] * f[keep]) / np.sum(u[keep] ** 2))


def wall_stiffness_estimates(data: MeasuredData) -> np.ndarray:
    """``E t`` [N/m] of every curve from its initial slope (cantilever ``k0 = 3 EI / L^3``)."""
    estimates = []
    for curve in data:
        slope = initial_slope(curve.deflection, curve.force)
        bending_stiffness = slope * curve.length**3 / 3.0
        estimates.append(bending_stiffness / (np.pi * curve.radius**3))
    return np.asarray(estimates)


def reference_specimen(data: MeasuredData) -> tuple[float, float]:
    """Geometric mean pressure [Pa] and radius [m] of the curves."""
    pressure = np.array([curve.pressure for curve in data])
    radius = np.array([curve.radius for curve in data])
    return float(np.exp(np.mean(np.log(pressure)))), float(np.exp(np.mean(np.log(radius))))


def initial_vector(data: MeasuredData, scaling: PivotScaling) -> np.ndarray:
    """Physics-based first guess of the fitted vector (see the module docstring)."""
    p_ref, r_ref = reference_specimen(data)
    estimates = wall_stiffness_estimates(data)
    if not np.all(np.isfinite(estimates) & (estimates > 0)):
        raise ValueError(f"{data.source}: cannot estimate the initial bending stiffness (the "
                         "first points of some curve do not rise with deflection)")
    wall_modulus = float(np.median(estimates))
    law = jt.SplineLaw.from_tension_field(
        wall_modulus, p_ref, r_ref, form="separate",
        residual_stiffness_ratio=scaling.residual_stiffness_ratio,
        pivots_per_regime=scaling.pivots_per_regime)
    if scaling.form == "paper":
        # The tension-field scaling in the paper's variable: moments ~ (p r^3)^1 exactly;
        # curvatures ~ p / (2 E t) at the reference radius, i.e. exponent 1 in p r^3.
        log_ak = np.log(np.asarray(law.curvature_scale) * p_ref)
        log_am = np.log(np.asarray(law.moment_scale) * p_ref * r_ref**3)
        ones = np.ones(scaling.pivot_count)
        return np.concatenate([log_ak, ones, log_am, ones])
    return scaling.vector(law, p_ref, r_ref)
