"""Model against measurement: how far off, is it noise, and where it fails.

:func:`compare` takes a :class:`fitting.FitResult` and reports

- errors per curve and overall: RMSE, largest error and bias (model - measured) [N];
- the noise: the fit's noise standard deviation (given by the user, or estimated without a
  model from the scatter of consecutive points, :func:`fitting.estimate_noise`);
- a verdict, *systematic or noise*, from two statistics:

  - the Wald-Wolfowitz runs test on the signs of the residuals along each curve (ordered by
    deflection), pooled over curves (Wald & Wolfowitz 1940): a misfitting model leaves long
    stretches of one sign, i.e. fewer runs than chance, ``z = (R - E[R]) / sd(R)`` with
    ``E[R] = sum_c (1 + 2 n+ n- / n)`` and
    ``Var R = sum_c 2 n+ n- (2 n+ n- - n) / (n^2 (n - 1))``;
  - chi-square of the residuals against the noise, ``chi^2 = sum w r^2 / sigma^2`` on
    ``n - k`` degrees of freedom (``k`` fitted coordinates);

  the residuals are called systematic when the runs test rejects at 1 % (one-sided) or
  ``chi^2 / dof > 2`` with a chi-square p-value below 0.1 %;
- where it fails: RMSE and bias grouped by pressure, radius and length; by the regime of the
  model's worst joint at each point (unwrinkled, wrinkled, collapsed); and by how far along
  the tube the wrinkling reaches (the outermost wrinkled joint, as a fraction of the length
  from the clamp).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.stats

import jaxtube as jt

from .._data.units import BAR_PER_PA, MM_PER_M
from .._json import finite_row

REGIME_NAMES = ("unwrinkled", "wrinkled", "collapsed")
RUNS_ALPHA = 0.01
CHI2_RATIO_SYSTEMATIC = 2.0
CHI2_ALPHA = 1e-3
#: Units in which tables and sentences give each specimen quantity: ``(unit, factor from SI)``.
SPECIMEN_UNITS = {"pressure": ("bar", BAR_PER_PA), "radius": ("mm", MM_PER_M),
                  "length": ("m", 1.0)}
#: Bins of the wrinkled extent (outermost wrinkled joint over the length; 0 = none).
EXTENT_EDGES = (0.0, 1e-9, 0.15, 0.3, 0.5, 1.0 + 1e-9)


@dataclasses.dataclass(frozen=True)
class ResidualVerdict:
    """Are the residuals noise? ``runs``/``runs_expected``/``runs_z``/``runs_p``: the pooled
    runs test (one-sided, few runs); ``chi2``, ``dof``, ``chi2_p``; ``lag1_correlation``: the
    pooled lag-1 autocorrelation along the curves; ``systematic`` and the verdict in words."""

    runs: int
    runs_expected: float
    runs_z: float
    runs_p: float
    chi2: float
    dof: int
    chi2_p: float
    lag1_correlation: float
    systematic: bool
    words: str


@dataclasses.dataclass(frozen=True)
class Group:
    """Residual statistics of the points sharing ``value`` of ``quantity`` (SI; a regime
    index; or an extent bin's lower edge): ``points``, ``rmse_N``, ``bias_N``, ``curves``."""

    quantity: str
    value: float
    label: str
    points: int
    rmse_N: float
    bias_N: float
    curves: tuple[str, ...]


@dataclasses.dataclass(frozen=True)
class Comparison:
    """The comparison of one fit with the measurements (see the module docstring)."""

    rmse_N: float
    max_error_N: float
    bias_N: float
    noise_N: float
    noise_given: bool
    curves: tuple[dict, ...]
    verdict: ResidualVerdict
    groups: tuple[Group, ...]

    def groups_of(self, quantity: str) -> list[Group]:
        return [g for g in self.groups if g.quantity == quantity]

    def to_json(self) -> dict:
        return {"rmse_N": self.rmse_N, "max_error_N": self.max_error_N, "bias_N": self.bias_N,
                "noise_N": self.noise_N, "noise_given": self.noise_given,
                "curves": list(self.curves),
                "verdict": finite_row(dataclasses.asdict(self.verdict)),
                "groups": [finite_row(dataclasses.asdict(g)) for g in self.groups]}

    def worst_groups(self, count: int = 3) -> list[Group]:
        """The groups (any quantity) with the largest RMSE relative to the overall RMSE."""
        return sorted(self.groups, key=lambda g: -g.rmse_N)[:count]


def point_table(result) -> dict[str, np.ndarray]:
    """Every measured point of ``result`` as flat arrays ``[n]``: curve index, deflection
    [m], residual (model - measured) [N], weight, pressure [Pa], radius [m], length [m],
    worst joint regime, wrinkled extent (outermost joint in regime >= 1 over the length, 0
    when none is)."""
    data = result.problem.data
    position = np.asarray(result.joint_position)
    rows = {k: [] for k in ("curve", "deflection", "residual", "weight", "pressure", "radius",
                            "length", "regime", "extent")}
    for c, (curve, force, regime) in enumerate(zip(data, result.force, result.joint_regime)):
        regime = np.asarray(regime)
        n = curve.point_count
        wrinkled = regime >= 1
        extent = np.where(wrinkled.any(axis=-1),
                          np.max(np.where(wrinkled, position[None, :], 0.0), axis=-1), 0.0)
        rows["curve"].append(np.full(n, c))
        rows["deflection"].append(curve.deflection)
        rows["residual"].append(np.asarray(force) - curve.force)
        rows["weight"].append(curve.weight)
        rows["pressure"].append(np.full(n, curve.pressure))
        rows["radius"].append(np.full(n, curve.radius))
        rows["length"].append(np.full(n, curve.length))
        rows["regime"].append(regime.max(axis=-1))
        # A wrinkled clamp joint (position 0) still counts as wrinkling at the root.
        rows["extent"].append(np.where(wrinkled.any(axis=-1), np.maximum(extent, 1e-6), 0.0))
    return {k: np.concatenate(v) for k, v in rows.items()}


def residual_verdict(result) -> ResidualVerdict:
    """Runs test and chi-square of ``result``'s residuals (module docstring)."""
    runs, expected, variance, lag_products, lag_norm = 0, 0.0, 0.0, 0.0, 0.0
    for curve, force in zip(result.problem.data, result.force):
        order = np.argsort(np.abs(curve.deflection), kind="stable")
        residual = (np.asarray(force) - curve.force)[order]
        signs = residual[residual != 0] > 0
        n = signs.size
        if n >= 2:
            n_pos = int(signs.sum())
            n_neg = n - n_pos
            runs += 1 + int(np.sum(signs[1:] != signs[:-1]))
            expected += 1 + 2.0 * n_pos * n_neg / n
            product = 2.0 * n_pos * n_neg
            variance += product * (product - n) / (n**2 * (n - 1))
        centred = residual - residual.mean()
        lag_products += float(np.sum(centred[1:] * centred[:-1]))
        lag_norm += float(np.sum(centred**2))
    z = (runs - expected) / math.sqrt(variance) if variance > 0 else 0.0
    runs_p = float(scipy.stats.norm.cdf(z))
    weights = np.concatenate([c.weight for c in result.problem.data])
    residual = np.concatenate([f - c.force for f, c in zip(result.force, result.problem.data)])
    chi2 = float(np.sum(weights * residual**2) / result.noise**2)
    dof = max(int(np.sum(weights > 0)) - len(result.problem.free_index), 1)
    chi2_p = float(scipy.stats.chi2.sf(chi2, dof))
    lag1 = lag_products / lag_norm if lag_norm > 0 else 0.0
    few_runs = runs_p < RUNS_ALPHA
    too_large = chi2 / dof > CHI2_RATIO_SYSTEMATIC and chi2_p < CHI2_ALPHA
    systematic = few_runs or too_large
    ratio = math.sqrt(chi2 / dof)
    if systematic:
        reasons = []
        if few_runs:
            reasons.append(f"the residuals keep one sign over long stretches of each curve "
                           f"({runs} runs where chance gives {expected:.0f}; z = {z:.1f}, "
                           f"p = {runs_p:.1e})")
        if too_large:
            reasons.append(f"they are {ratio:.2g}x the noise (chi^2/dof = {chi2 / dof:.3g}, "
                           f"p = {chi2_p:.1e})")
        words = "Systematic: " + " and ".join(reasons) + "."
    else:
        words = (f"Noise: the residuals change sign as often as chance predicts ({runs} runs, "
                 f"expected {expected:.0f}, p = {runs_p:.2f}) and are {ratio:.2g}x the noise "
                 f"(chi^2/dof = {chi2 / dof:.3g}).")
    return ResidualVerdict(runs=runs, runs_expected=expected, runs_z=z, runs_p=runs_p,
                           chi2=chi2, dof=dof, chi2_p=chi2_p, lag1_correlation=lag1,
                           systematic=systematic, words=words)


def _group(quantity, value, label, keep, table, names) -> Group:
    r = table["residual"][keep]
    w = table["weight"][keep]
    curves = tuple(sorted({names[int(c)] for c in table["curve"][keep]}))
    return Group(quantity=quantity, value=float(value), label=label, points=int(keep.sum()),
                 rmse_N=float(np.sqrt(np.sum(w * r**2) / np.sum(w))),
                 bias_N=float(np.sum(w * r) / np.sum(w)), curves=curves)


def residual_groups(result) -> list[Group]:
    """Residual RMSE and bias grouped by pressure, radius, length, regime and wrinkled
    extent (module docstring)."""
    table = point_table(result)
    names = [curve.name for curve in result.problem.data]
    groups = []
    for quantity, (unit, factor) in SPECIMEN_UNITS.items():
        for value in np.unique(table[quantity]):
            keep = table[quantity] == value
            groups.append(_group(quantity, value, f"{value * factor:.4g} {unit}", keep, table,
                                 names))
    for regime, name in enumerate(REGIME_NAMES):
        keep = table["regime"] == regime
        if keep.any():
            groups.append(_group("regime", regime, name, keep, table, names))
    edges = EXTENT_EDGES
    for low, high in zip(edges[:-1], edges[1:]):
        keep = (table["extent"] >= low) & (table["extent"] < high)
        if keep.any():
            label = ("no wrinkle" if high <= 1e-9 else
                     f"wrinkled up to {low:.0%}-{min(high, 1.0):.0%} of L")
            groups.append(_group("wrinkled_extent", low, label, keep, table, names))
    return groups


def compare(result) -> Comparison:
    """Compare a fit with its measurements (module docstring)."""
    rows = result.curve_errors()
    residual = np.concatenate([f - c.force for f, c in zip(result.force, result.problem.data)])
    for row, curve in zip(rows, result.problem.data):
        row.update(pressure_bar=curve.pressure / jt.unit_factor("pressure", "bar"),
                   radius_m=curve.radius,
                   length_m=curve.length, points=curve.point_count)
    return Comparison(rmse_N=result.rmse, max_error_N=float(np.max(np.abs(residual))),
                      bias_N=float(np.mean(residual)), noise_N=result.noise,
                      noise_given=result.problem.noise_given, curves=tuple(rows),
                      verdict=residual_verdict(result), groups=tuple(residual_groups(result)))
