"""The outcome of a calibration: estimates with uncertainty, identifiability in words,
goodness of fit, prediction with confidence bands, and the parameters file.

Parameters file (JSON, ``format = "jaxtube-fit"``, ``version = 1``)::

    {"format": "jaxtube-fit", "version": 1,
     "law": {"type": "SplineLaw", "form": "paper", "pivots_per_regime": [2, 2, 1],
             "residual_stiffness_ratio": 0.01,
             "curvature_scale": [...], "curvature_exponent": [...],
             "moment_scale": [...], "moment_exponent": [...],
             "curvature_radius_exponent": null | [...], "moment_radius_exponent": null | [...]},
     "parameters": [{"name": "kappa[1].A", "value": ..., "standard_error": ...,
                     "identified": true, "fixed": false}, ...],
     "reference": {"pressure_Pa": ..., "radius_m": ...},
     "fitted_coordinates": [...], "covariance": [[...]],   # of the free coordinates
     "noise_N": ..., "rmse_N": ..., "curves": [{"curve": ..., "rmse_N": ...}, ...],
     "convergence": {...}, "identifiability": ["...", ...], "data": "path"}

The ``law`` block is the fitted spline without the effects (its ``linear_share`` is read
if present, default 0); ``effects`` holds each fitted effect's values. :func:`load_law`
reads the law back (``jaxtube simulate --params``, ``jaxtube sweep --params``) with the
model-structure extensions (``radius_scaling``, ``unwrinkled_linearity``) folded in;
``jaxtube predict`` rebuilds the fitted model from ``coordinates``, effects included.
"""

from __future__ import annotations

import dataclasses
import math

import jax.numpy as jnp
import numpy as np

import jaxtube as jt

from .._bench.rig import unpad
from .._bench.scaling import COORDINATES, PivotScaling
from .._json import finite_or_none, finite_row
from .problem import (
    STRONG_CORRELATION,
    UNIDENTIFIED_SE,
    UNIDENTIFIED_SE_EXPONENT,
    Convergence,
    FitProblem,
    forces_and_sensitivity,
    specimen_arrays,
)

FORMAT = "jaxtube-fit"
VERSION = 1
Z_95 = 1.959963984540054


@dataclasses.dataclass(frozen=True)
class ParameterEstimate:
    """One reported parameter (``A`` in SI, exponents dimensionless)."""

    name: str
    value: float
    standard_error: float  # nan when fixed, inf when not identified
    fixed: bool
    identified: bool


@dataclasses.dataclass(frozen=True)
class FitResult:
    """A fitted calibration. Build it with :func:`fitting.fit`.

    Attributes:
        problem: the least-squares problem (data, rig, scaling, noise, fixed values).
        free_values: the optimum in the fitted coordinates ``[n_free]``.
        covariance: their Laplace covariance ``[n_free, n_free]`` (pseudo-inverse of the
            information: the uncertainty of what the data determine).
        free_standard_errors: ``[n_free]``; inf for coordinates the data do not determine.
        parameters: one :class:`ParameterEstimate` per reported name.
        identifiability: sentences on what the data cannot determine (empty if all is).
        residual_variance: ``chi^2 / dof`` in units of the noise variance.
        force: model forces per curve, original point order ``[list of [P_c]]`` [N].
        joint_regime: per curve ``[P_c, J]``; joint_position ``[J]`` (0 clamp .. 1 tip).
        convergence: the optimiser's report.
        residual: ``[n_data + n_names]`` residuals at the optimum in noise units (data rows
            in the padded ``[C, P]`` order, then prior rows).
        jacobian: ``[n_data + n_names, n_names]`` their derivatives w.r.t. every coordinate,
            free or held (score tests and the diagnosis use the held columns).
    """

    problem: FitProblem
    free_values: np.ndarray
    covariance: np.ndarray
    free_standard_errors: np.ndarray
    parameters: tuple[ParameterEstimate, ...]
    identifiability: tuple[str, ...]
    residual_variance: float
    force: tuple[np.ndarray, ...]
    joint_regime: tuple[np.ndarray, ...]
    joint_position: np.ndarray
    convergence: Convergence
    residual: np.ndarray
    jacobian: np.ndarray

    # -- construction --------------------------------------------------------------------

    @classmethod
    def from_optimum(cls, problem: FitProblem, x, report, convergence) -> FitResult:
        n_data = problem.batch.force.size
        r, jac = report["r"], report["jac"]
        pred = report["prediction"]
        data_r = r[:n_data][problem.batch.weight.reshape(-1) > 0]
        n_free = x.size
        dof = max(data_r.size - n_free, 1)
        residual_variance = float(data_r @ data_r) / dof
        info = jac.T @ jac
        scale = np.sqrt(np.maximum(np.diag(info), 1e-300))
        scaled = info / np.outer(scale, scale)
        # Identification: a tiny ridge on the correlation-scaled information leaves the
        # errors of identified coordinates as they are and gives coordinates the data do not
        # see an error ~1e5 x their scale, which the thresholds flag.
        factor = 1.0 if problem.noise_given else residual_variance
        with np.errstate(over="ignore"):  # a column the data do not see: inf, flagged below
            ridge = np.linalg.inv(scaled + 1e-10 * np.eye(n_free)) / np.outer(scale, scale)
        se_free = np.sqrt(np.maximum(np.diag(ridge) * factor, 0.0))
        thresholds = np.array([_threshold(problem, n) for n in problem.free_names])
        se_free = np.where(se_free > thresholds, np.inf, se_free)
        # Covariance for errors and bands: the pseudo-inverse, i.e. the uncertainty of what
        # the data determine (directions they do not see are left out, see the README).
        covariance = np.linalg.pinv(scaled, rcond=1e-8, hermitian=True) / np.outer(scale, scale)
        covariance = covariance * factor
        params, words = _report_parameters(problem, x, covariance, se_free)
        force = unpad(problem.batch, np.asarray(pred.force))
        regime = unpad(problem.batch, np.asarray(pred.joint_regime))
        return cls(problem=problem, free_values=np.asarray(x), covariance=covariance,
                   free_standard_errors=se_free, parameters=tuple(params),
                   identifiability=tuple(words),
                   residual_variance=residual_variance, force=tuple(force),
                   joint_regime=tuple(regime),
                   joint_position=np.asarray(pred.joint_position)[0, 0],
                   convergence=convergence, residual=np.asarray(r),
                   jacobian=np.asarray(report["full_jacobian"]))

    # -- model ------------------------------------------------------------------------------

    @property
    def vector(self) -> np.ndarray:
        full = np.array(self.problem.base, float)
        full[np.asarray(self.problem.free_index)] = self.free_values
        return full

    @property
    def law(self) -> jt.SplineLaw:
        """The fitted bending law."""
        p_ref, r_ref = self.problem.reference
        return self.problem.scaling.law(jnp.asarray(self.vector), p_ref, r_ref)

    def parameter(self, name: str) -> ParameterEstimate:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)

    # -- goodness of fit ---------------------------------------------------------------------

    @property
    def noise(self) -> float:
        return self.problem.noise

    def curve_errors(self) -> list[dict]:
        """Per curve: name, RMSE, max |error|, bias [N] (model - measured)."""
        rows = []
        for curve, force in zip(self.problem.data, self.force):
            err = force - curve.force
            rows.append({"curve": curve.name, "rmse_N": float(np.sqrt(np.mean(err**2))),
                         "max_error_N": float(np.max(np.abs(err))),
                         "bias_N": float(np.mean(err))})
        return rows

    @property
    def rmse(self) -> float:
        err = np.concatenate([f - c.force for f, c in zip(self.force, self.problem.data)])
        return float(np.sqrt(np.mean(err**2)))

    # -- prediction with bands ---------------------------------------------------------------

    def predict(self, pressure, radius, length, deflection, band: bool = True):
        """Model force [N] at tip deflections ``[C, P]`` [m] of specimens ``[C]`` (Pa, m, m),
        and its standard deviation from the parameter covariance (delta method: one JVP per
        fitted coordinate through the solve; zeros when ``band`` is False). Directions of the
        parameters that the data do not determine are not in the band: beyond the measured
        range it is a lower bound. Raises if any equilibrium fails to converge."""
        deflection = np.atleast_2d(np.asarray(deflection, float))
        arrays = specimen_arrays(np.atleast_1d(pressure), np.atleast_1d(radius),
                                 np.atleast_1d(length), deflection)
        force, sens, converged = forces_and_sensitivity(self.problem, self.free_values, arrays)
        if band:
            sd = _delta_method(sens, self.covariance)
        else:
            sd = np.zeros_like(force)
        if not np.all(converged):
            raise RuntimeError(f"prediction: {int(np.sum(~converged))} equilibrium solves did "
                               "not converge")
        return force, sd

    # -- output -------------------------------------------------------------------------------

    def to_json(self) -> dict:
        law = self.law
        scaling = self.problem.scaling

        def listed(value):
            return None if value is None else np.asarray(value, float).tolist()

        return {
            "format": FORMAT, "version": VERSION,
            "law": {"type": "SplineLaw", "form": scaling.form,
                    "pivots_per_regime": list(scaling.pivots_per_regime),
                    "residual_stiffness_ratio": scaling.residual_stiffness_ratio,
                    "curvature_scale": listed(law.curvature_scale),
                    "curvature_exponent": listed(law.curvature_exponent),
                    "moment_scale": listed(law.moment_scale),
                    "moment_exponent": listed(law.moment_exponent),
                    "curvature_radius_exponent": listed(law.curvature_radius_exponent),
                    "moment_radius_exponent": listed(law.moment_radius_exponent)},
            "parameters": [finite_row(dataclasses.asdict(p)) for p in self.parameters],
            "reference": {"pressure_Pa": self.problem.reference[0],
                          "radius_m": self.problem.reference[1]},
            "coordinates": {"names": list(self.problem.names),
                            "values": self.vector.tolist(),
                            "free_index": list(self.problem.free_index)},
            "fitted_coordinates": self.problem.free_names,
            "fitted_values": self.free_values.tolist(),
            "free_standard_errors": [finite_or_none(v) for v in self.free_standard_errors],
            "covariance": [[finite_or_none(v) for v in row] for row in self.covariance],
            "noise_N": self.noise, "noise_given": self.problem.noise_given,
            "residual_variance": self.residual_variance,
            "rmse_N": self.rmse, "curves": self.curve_errors(),
            "segments": self.problem.rig.segments,
            "convergence": dataclasses.asdict(self.convergence),
            "identifiability": list(self.identifiability),
            "effects": {e.name: {p.name: float(self.vector[list(self.problem.names).index(
                f"{e.name}.{p.name}")]) for p in e.parameters} for e in self.problem.effects},
            "data": str(self.problem.data.source),
        }

    def table(self) -> str:
        """The parameter table as text (value, standard error, status)."""
        lines = [f"{'parameter':<14}{'value':>14}{'std. error':>14}  status",
                 "-" * 58]
        for p in self.parameters:
            if p.fixed:
                se, status = "", "fixed"
            elif p.name in self.convergence.held:
                se, status = "--", "HELD (not determined by the data)"
            elif not p.identified:
                se, status = "--", "NOT IDENTIFIED"
            else:
                se, status = f"{p.standard_error:.4g}", ""
            lines.append(f"{p.name:<14}{p.value:>14.6g}{se:>14}  {status}")
        return "\n".join(lines)


def _effect_parameter(problem: FitProblem, name: str):
    for effect in problem.effects:
        for parameter in effect.parameters:
            if name == f"{effect.name}.{parameter.name}":
                return parameter
    return None


def _threshold(problem: FitProblem, name: str) -> float:
    """Standard error above which a fitted coordinate counts as not identified."""
    parameter = _effect_parameter(problem, name)
    if parameter is not None:
        return 1e3 * abs(parameter.typical)
    return UNIDENTIFIED_SE if name.endswith(".A") else UNIDENTIFIED_SE_EXPONENT


def _report_parameters(problem: FitProblem, x, covariance, se_free):
    """Reported (A, B, C) with delta-method errors, and identifiability sentences."""
    scaling: PivotScaling = problem.scaling
    names = problem.names
    full = np.array(problem.base, float)
    free = np.asarray(problem.free_index)
    full[free] = x
    position = {names[i]: k for k, i in enumerate(problem.free_index)}
    p_ref, r_ref = problem.reference
    physical = scaling.physical(full, p_ref, r_ref)
    log_ref = (np.array([math.log(p_ref * r_ref**3)]) if scaling.form == "paper"
               else np.array([math.log(p_ref), math.log(r_ref)]))
    n_free = len(problem.free_index)
    estimates, words = [], []
    unidentified = set()
    for i, name in enumerate(names):
        effect_parameter = _effect_parameter(problem, name)
        value = float(full[i]) if effect_parameter is not None else physical[name]
        fixed = name not in position
        if fixed:
            estimates.append(ParameterEstimate(name, value, math.nan, True, True))
            continue
        if effect_parameter is not None:
            se = float(se_free[position[name]])
            identified = bool(math.isfinite(se))
        elif name.endswith(".A"):
            # A = exp(log a - sum_e exponent_e log ref_e): gradient in the free coordinates.
            grad = np.zeros(n_free)
            grad[position[name]] = value
            infinite = not math.isfinite(se_free[position[name]])
            for e, lr in zip(scaling.exponents, log_ref):
                other = name[:-1] + e
                if other in position:
                    grad[position[other]] = -value * lr
                    infinite |= not math.isfinite(se_free[position[other]]) and lr != 0
            se = math.inf if infinite else math.sqrt(max(grad @ covariance @ grad, 0.0))
            identified = bool(math.isfinite(se) and se_free[position[name]] <= UNIDENTIFIED_SE)
        else:
            se = float(se_free[position[name]])
            identified = bool(math.isfinite(se) and se <= UNIDENTIFIED_SE_EXPONENT)
        if not identified:
            unidentified.add(name)
        estimates.append(ParameterEstimate(name, value, se if identified else math.inf,
                                           False, identified))
    # A pivot is unresolved when its increment at the reference specimen (log a) is not
    # determined; an A that is unidentified only through its exponent is not.
    unresolved = {name for name in names if name.endswith(".A") and name in position
                  and _effect_parameter(problem, name) is None
                  and not math.isfinite(se_free[position[name]])}
    unidentified_effects = sorted(n for n in unidentified if _effect_parameter(problem, n))
    unidentified = {n for n in unidentified if n not in unidentified_effects}
    if unidentified_effects:
        words.append(f"Not identified: {', '.join(unidentified_effects)}: the data do not "
                     "determine these effect parameters.")
    words += _identifiability_words(problem, unidentified, unresolved, covariance)
    return estimates, words


def _identifiability_words(problem: FitProblem, unidentified, unresolved_scales, covariance):
    data = problem.data
    scaling = problem.scaling
    words = []
    pressure = np.array([c.pressure for c in data])
    radius = np.array([c.radius for c in data])
    pr3 = pressure * radius**3
    spread = float(pr3.max() / pr3.min())
    radius_spread = float(radius.max() / radius.min())
    pressure_spread = float(pressure.max() / pressure.min())
    def pivot(name):
        return int(name.split("[")[1].split("]")[0])

    # A pivot whose scale is not determined: its exponents cannot be either.
    unresolved = sorted({pivot(n) for n in unresolved_scales})
    if unresolved:
        regimes = sorted({scaling.regime_of_pivot(i - 1) for i in unresolved})
        regime_names = ", ".join(("unwrinkled", "wrinkled", "collapsed")[r] for r in regimes)
        names = sorted(n for n in unidentified if pivot(n) in unresolved)
        words.append(
            f"Not identified: {', '.join(names)} (pivot(s) {', '.join(map(str, unresolved))}, "
            f"{regime_names} regime). The curves do not reach or resolve these pivots: "
            "points further into wrinkling and along the collapse plateau, or fewer pivots "
            "(--pivots), determine them. Predictions beyond the measured range depend on "
            "them and carry no band there.")
    # With little spread of p r^3 in the data no exponent can be determined, whatever the
    # pivots; otherwise only the exponents of resolved pivots are worth a sentence.
    narrow = spread < 1.5
    exps = sorted(n for n in unidentified if n.endswith(".B")
                  and (narrow or pivot(n) not in unresolved))
    scales = sorted(n for n in unidentified if n.endswith(".A") and pivot(n) not in unresolved)
    if exps:
        words.append(
            f"Not identified: {', '.join(exps)}. B is the exponent of the scaling variable; "
            f"the data cover p r^3 from {pr3.min():.3g} to {pr3.max():.3g} N m (a ratio of "
            f"{spread:.2f}), pressures over a ratio of {pressure_spread:.2f} and radii over "
            f"{radius_spread:.2f}. Curves at clearly different values of p r^3 (pressures or "
            "radii) determine B."
            + (f" The pivots themselves are determined at the reference specimen, but "
               f"{', '.join(scales)} (A at p r^3 = 1) follow only with B." if scales else ""))
    radius_exps = sorted(n for n in unidentified if n.endswith(".C")
                         and pivot(n) not in unresolved)
    if radius_exps:
        words.append(
            f"Not identified: {', '.join(radius_exps)}. C is the radius exponent of the "
            f"separate form; the data's radii span a ratio of {radius_spread:.2f}. Curves "
            "at several radii determine C.")
    # Strongly correlated identified pairs.
    free = problem.free_names
    sd = np.sqrt(np.maximum(np.diag(covariance), 1e-300))
    corr = covariance / np.outer(sd, sd)
    pairs = []
    for i in range(len(free)):
        for j in range(i + 1, len(free)):
            if free[i] in unidentified or free[j] in unidentified:
                continue
            if abs(corr[i, j]) > STRONG_CORRELATION:
                pairs.append(f"{free[i]} and {free[j]} ({corr[i, j]:+.3f})")
    if pairs:
        words.append("Strongly correlated (the data determine their combination better than "
                     "each): " + "; ".join(pairs[:8]) + ("; ..." if len(pairs) > 8 else "") + ".")
    return words


def _delta_method(sensitivity, covariance) -> np.ndarray:
    """Standard deviation of the force, ``sqrt(g^T Cov g)`` per point (``g = dF/dtheta``)."""
    variance = np.einsum("cpi,ij,cpj->cp", sensitivity, covariance, sensitivity)
    return np.sqrt(np.maximum(variance, 0.0))


__all__ = ["FitResult", "ParameterEstimate", "COORDINATES"]
