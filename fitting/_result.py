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

:func:`load_law` reads the law back (``jaxtube simulate --params``, ``jaxtube predict``).
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import jax.numpy as jnp
import numpy as np

import jaxtube as jt

from ._calibrate import (
    STRONG_CORRELATION,
    UNIDENTIFIED_SE,
    UNIDENTIFIED_SE_EXPONENT,
    Convergence,
    FitProblem,
    forces_and_sensitivity,
    model_forces,
    specimen_arrays,
)
from ._rig import unpad
from ._scaling import COORDINATES, PivotScaling

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
        covariance: their Laplace covariance ``[n_free, n_free]`` (pseudo-inverse).
        free_standard_errors: ``[n_free]``; inf for coordinates the data do not determine.
        parameters: one :class:`ParameterEstimate` per reported name.
        identifiability: sentences on what the data cannot determine (empty if all is).
        residual_variance: ``chi^2 / dof`` in units of the noise variance.
        force: model forces per curve, original point order ``[list of [P_c]]`` [N].
        joint_regime: per curve ``[P_c, J]``; joint_position ``[J]`` (0 clamp .. 1 tip).
        convergence: the optimiser's report.
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
        evals, evecs = np.linalg.eigh(scaled)
        keep = evals > 1e-10 * max(float(evals.max()), 1e-300)
        inv_scaled = (evecs[:, keep] / evals[keep]) @ evecs[:, keep].T
        # Directions the data do not see: their coordinates get an infinite error.
        null_loading = np.sum(evecs[:, ~keep] ** 2, axis=1)
        covariance = inv_scaled / np.outer(scale, scale)
        if not problem.noise_given:
            covariance = covariance * residual_variance
        se_free = np.sqrt(np.maximum(np.diag(covariance), 0.0))
        se_free = np.where(null_loading > 0.01, np.inf, se_free)
        params, words = _report_parameters(problem, x, covariance, se_free)
        force = unpad(problem.batch, np.asarray(pred.force))
        regime = unpad(problem.batch, np.asarray(pred.joint_regime))
        return cls(problem=problem, free_values=np.asarray(x), covariance=covariance,
                   free_standard_errors=se_free, parameters=tuple(params), identifiability=tuple(words),
                   residual_variance=residual_variance, force=tuple(force),
                   joint_regime=tuple(regime),
                   joint_position=np.asarray(pred.joint_position)[0, 0],
                   convergence=convergence)

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
        and its standard deviation from the parameter covariance (delta method; zeros when
        ``band`` is False). Raises if any equilibrium fails to converge."""
        deflection = np.atleast_2d(np.asarray(deflection, float))
        arrays = specimen_arrays(np.atleast_1d(pressure), np.atleast_1d(radius),
                                 np.atleast_1d(length), deflection)
        if band:
            force, sens, converged = forces_and_sensitivity(self.problem, self.free_values,
                                                            arrays)
            finite = np.where(np.isfinite(self.covariance), self.covariance, 0.0)
            variance = np.einsum("cpi,ij,cpj->cp", sens, finite, sens)
            unidentified = ~np.isfinite(self.standard_errors_free)
            # A coordinate the data do not determine makes the band unbounded where the
            # prediction depends on it.
            reach = np.abs(sens[..., unidentified]).max(axis=-1, initial=0.0)
            sd = np.where(reach > 1e-9 * np.maximum(np.abs(force), 1e-300), np.inf,
                          np.sqrt(np.maximum(variance, 0.0)))
        else:
            force, pred = model_forces(self.problem, self.free_values, arrays)
            converged, sd = np.asarray(pred.converged), np.zeros_like(force)
        if not np.all(converged):
            raise RuntimeError(f"prediction: {int(np.sum(~converged))} equilibrium solves did "
                               "not converge")
        return force, sd

    @property
    def standard_errors_free(self) -> np.ndarray:
        """Standard errors of the fitted coordinates (``log a`` and exponents); inf where
        the data do not determine them."""
        return self.free_standard_errors

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
            "parameters": [_finite_or_none(dataclasses.asdict(p)) for p in self.parameters],
            "reference": {"pressure_Pa": self.problem.reference[0],
                          "radius_m": self.problem.reference[1]},
            "fitted_coordinates": self.problem.free_names,
            "fitted_values": self.free_values.tolist(),
            "covariance": [[_finite(v) for v in row] for row in self.covariance],
            "noise_N": self.noise, "noise_given": self.problem.noise_given,
            "residual_variance": self.residual_variance,
            "rmse_N": self.rmse, "curves": self.curve_errors(),
            "segments": self.problem.rig.segments,
            "convergence": dataclasses.asdict(self.convergence),
            "identifiability": list(self.identifiability),
            "data": str(self.problem.data.source),
        }

    def table(self) -> str:
        """The parameter table as text (value, standard error, status)."""
        lines = [f"{'parameter':<14}{'value':>14}{'std. error':>14}  status",
                 "-" * 58]
        for p in self.parameters:
            if p.fixed:
                se, status = "", "fixed"
            elif not p.identified:
                se, status = "--", "NOT IDENTIFIED"
            else:
                se, status = f"{p.standard_error:.4g}", ""
            lines.append(f"{p.name:<14}{p.value:>14.6g}{se:>14}  {status}")
        return "\n".join(lines)


def _finite(value):
    value = float(value)
    return value if math.isfinite(value) else None


def _finite_or_none(row: dict) -> dict:
    return {k: (_finite(v) if isinstance(v, float) else v) for k, v in row.items()}


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
    for name in names:
        value = physical[name]
        fixed = name not in position
        if fixed:
            estimates.append(ParameterEstimate(name, value, math.nan, True, True))
            continue
        if name.endswith(".A"):
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
            identified = math.isfinite(se) and se_free[position[name]] <= UNIDENTIFIED_SE
        else:
            se = float(se_free[position[name]])
            identified = math.isfinite(se) and se <= UNIDENTIFIED_SE_EXPONENT
        if not identified:
            unidentified.add(name)
        estimates.append(ParameterEstimate(name, value, se if identified else math.inf,
                                           False, identified))
    words += _identifiability_words(problem, unidentified, covariance, position)
    return estimates, words


def _identifiability_words(problem: FitProblem, unidentified, covariance, position):
    data = problem.data
    scaling = problem.scaling
    words = []
    pr3 = data.pressures() * data.radii() ** 3
    spread = float(pr3.max() / pr3.min())
    radius_spread = float(data.radii().max() / data.radii().min())
    pressure_spread = float(data.pressures().max() / data.pressures().min())
    exps = sorted(n for n in unidentified if n.endswith(".B"))
    if exps:
        words.append(
            f"Not identified: {', '.join(exps)}. B is the exponent of the scaling variable; "
            f"the data cover p r^3 from {pr3.min():.3g} to {pr3.max():.3g} N m (a ratio of "
            f"{spread:.2f}), pressures over a ratio of {pressure_spread:.2f} and radii over "
            f"{radius_spread:.2f}. Curves at clearly different pressures or radii determine B.")
    radius_exps = sorted(n for n in unidentified if n.endswith(".C"))
    if radius_exps:
        words.append(
            f"Not identified: {', '.join(radius_exps)}. C is the radius exponent of the "
            f"separate form; the data's radii span a ratio of {radius_spread:.2f}. Curves "
            "at several radii determine C.")
    scales = sorted(n for n in unidentified if n.endswith(".A"))
    if scales:
        regimes = sorted({scaling.regime_of_pivot(int(n.split("[")[1].split("]")[0]) - 1)
                          for n in scales})
        regime_names = ", ".join(("unwrinkled", "wrinkled", "collapsed")[r] for r in regimes)
        words.append(
            f"Not identified: {', '.join(scales)} (pivots of the {regime_names} regime). "
            "The curves do not constrain these pivots separately: points further along the "
            "collapse plateau, or fewer pivots (--pivots), determine them.")
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


def load_law(path) -> jt.SplineLaw:
    """The bending law of a parameters file written by ``jaxtube fit`` (clear errors)."""
    path = Path(path)
    try:
        document = json.loads(path.read_text())
    except FileNotFoundError:
        raise ValueError(f"{path}: parameters file not found") from None
    except json.JSONDecodeError as error:
        raise ValueError(f"{path}: not valid JSON (line {error.lineno}, column "
                         f"{error.colno}): {error.msg}") from None
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise ValueError(f"{path}: expected a jaxtube fit parameters file "
                         f"(\"format\": \"{FORMAT}\")")
    if document.get("version") != VERSION:
        raise ValueError(f"{path}: unsupported version {document.get('version')!r}; "
                         f"expected {VERSION}")
    law = document.get("law", {})
    if law.get("type") != "SplineLaw":
        raise ValueError(f"{path}: law.type must be 'SplineLaw', got {law.get('type')!r}")
    try:
        return jt.SplineLaw(
            curvature_scale=np.asarray(law["curvature_scale"], float),
            curvature_exponent=np.asarray(law["curvature_exponent"], float),
            moment_scale=np.asarray(law["moment_scale"], float),
            moment_exponent=np.asarray(law["moment_exponent"], float),
            curvature_radius_exponent=None if law.get("curvature_radius_exponent") is None
            else np.asarray(law["curvature_radius_exponent"], float),
            moment_radius_exponent=None if law.get("moment_radius_exponent") is None
            else np.asarray(law["moment_radius_exponent"], float),
            residual_stiffness_ratio=float(law.get("residual_stiffness_ratio", 0.01)),
            pivots_per_regime=tuple(int(n) for n in law["pivots_per_regime"]))
    except KeyError as error:
        raise ValueError(f"{path}: law.{error.args[0]} is missing") from None
    except (TypeError, ValueError) as error:
        raise ValueError(f"{path}: invalid law: {error}") from None


__all__ = ["FitResult", "ParameterEstimate", "load_law", "COORDINATES"]
