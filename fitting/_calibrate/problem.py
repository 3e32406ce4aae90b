"""Calibration: fit the pivot scaling of the bending law to measured force-deflection curves.

All curves are fitted in one joint weighted least-squares problem in force,

    minimise  sum_i w_i ((F_model(u_i; theta) - F_i) / sigma)^2  (+ prior terms),

with ``F_model`` the jaxtube equilibrium force at the measured tip deflection ``u_i``
(displacement control, so plateau points count; :mod:`fitting._bench.rig`). The residual
Jacobian comes from forward-mode derivatives through the equilibrium solve, which jaxtube
gives by the implicit function theorem (never by differentiating the Newton loop).

Optimiser: Levenberg-Marquardt with Marquardt's diagonal scaling and Nielsen's damping
update (Madsen, Nielsen & Tingleff, *Methods for non-linear least squares problems*, 2004,
section 3.2); bounds by projection; an optional robust (Huber) loss by iteratively
reweighted least squares; optional multi-start from perturbed physics-based guesses.
A step at which any equilibrium fails to converge is rejected (the damping grows), never
silently accepted.

Uncertainty (Laplace / Gauss-Newton): ``Cov = s^2 (J^T J)^+`` in the fitted coordinates,
``s^2`` the residual variance per degree of freedom when the noise is estimated (1 when the
user gives it); standard errors of the reported ``A, B, C`` by the delta method. Parameters
the data cannot identify are found from the scaled information matrix and flagged in words.
Prediction bands: ``Var F(u) = g^T Cov g`` with ``g = dF/dtheta``, one JVP per fitted
coordinate through the solve (the delta method).

Noise estimate (when not given): model-free differences that annihilate local quadratics on
each curve's unequally spaced deflections, pooled over curves (:mod:`fitting._calibrate.noise`).

Stopping: besides the classical rules, a stagnation rule: when chi^2 (noise units) fell by
less than ``stall_chi2`` over the last ``stall_window`` accepted iterations, the fit has
converged in the statistical sense (a change of chi^2 by 1 is one standard deviation of one
parameter) and only drifts along directions the data hardly determine.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

import jaxtube as jt

from .._bench.rig import CantileverRig, CurveBatch, TubeModel, batch_curves, unpad
from .._bench.scaling import PivotScaling, initial_vector, reference_specimen
from .._data import MeasuredData
from .noise import estimate_noise
from .outcome import FitOutcome, ending

# Default bounds of the exponents B and C (physics: 0 to 3 for p^B r^C; generous), and of
# each scale A: within a factor SCALE_RANGE of the physics-based first guess. Coordinates
# the data do not determine drift to these bounds instead of to infinity; they are then
# flagged as not identified.
EXPONENT_BOUNDS = (-1.0, 4.0)
SCALE_RANGE = 100.0
# A fitted coordinate whose standard error exceeds this is "not identified" (log a: a
# factor e; exponents: 0.5, i.e. a factor ~2 per decade of the scaling variable).
UNIDENTIFIED_SE = 1.0
UNIDENTIFIED_SE_EXPONENT = 0.5
STRONG_CORRELATION = 0.98


class FitError(RuntimeError):
    """The calibration could not start or the equilibrium solves failed."""


@dataclasses.dataclass(frozen=True)
class Prior:
    """Gaussian prior on a fitted coordinate: exponents in their own units, ``A`` on
    ``log A`` (``sd`` is then a relative spread; 0.1 is about 10 %)."""

    mean: float
    sd: float


@dataclasses.dataclass(frozen=True)
class FitOptions:
    """User choices of a calibration.

    Attributes:
        noise_N: force noise standard deviation [N]; None = :func:`estimate_noise`.
        fixed: ``{name: value}`` coordinates held fixed (``A`` in SI, exponents as is).
        priors: ``{name: Prior}``.
        bounds: ``{name: (low, high)}`` for exponents (default :data:`EXPONENT_BOUNDS`).
        loss: ``"linear"`` (least squares) or ``"huber"`` (robust, threshold
            ``huber_threshold`` noise standard deviations).
        multistart: number of starts (1 = the physics-based guess only).
        max_iterations, ftol, gtol, chi2_tol: Levenberg-Marquardt stopping rules (relative
            loss decrease, gradient, and absolute decrease of chi^2 in noise units).
        stall_chi2, stall_window: stagnation: stop (converged) when chi^2 in noise units fell
            by less than ``stall_chi2`` over the last ``stall_window`` iterations.
        hold_undetermined: :func:`fitting.fit` holds the coordinates the data do not
            determine (infinite standard error) at the physics-based first guess and refits
            the rest (as the diagnosis does); the result says which.
        stop_on_bound: names of coordinates: the fit ends (``FitOutcome.back_on_bound``)
            once every one of them is on a bound and held there by the active set (the
            descent direction points out of the box); the diagnosis' second start of a refit
            uses it (:func:`fitting._diagnose.selection.refit_candidate`).
        seed: of the multi-start perturbations.
        progress: show a progress bar.
    """

    noise_N: float | None = None
    fixed: Mapping[str, float] = dataclasses.field(default_factory=dict)
    priors: Mapping[str, Prior] = dataclasses.field(default_factory=dict)
    bounds: Mapping[str, tuple[float, float]] = dataclasses.field(default_factory=dict)
    loss: str = "linear"
    huber_threshold: float = 1.345
    multistart: int = 1
    max_iterations: int = 60
    ftol: float = 1e-6
    chi2_tol: float = 1e-3
    gtol: float = 1e-8
    stall_chi2: float = 1.0
    stall_window: int = 5
    hold_undetermined: bool = True
    stop_on_bound: tuple[str, ...] = ()
    seed: int = 0
    progress: bool = True


@dataclasses.dataclass(frozen=True)
class Convergence:
    """How the optimisation ended."""

    converged: bool
    message: str
    iterations: int
    evaluations: int  # residual + Jacobian evaluations (always together)
    solver_calls: int  # equilibrium path solves (one per curve per evaluation)
    seconds: float
    starts: int
    start_costs: tuple[float, ...]
    held: tuple[str, ...] = ()  # coordinates held at the first guess (not determined)


# --------------------------------------------------------------------------------------------
# Residuals and Jacobians (compiled once per rig, scaling and data shape)
# --------------------------------------------------------------------------------------------


def _model_forces(vector, reference, batch_arrays, *, rig, scaling, effects=()):
    n_law = len(scaling.names())
    law = scaling.law(vector[:n_law], reference[0], reference[1])
    instances, k = [], n_law
    for effect in effects:
        count = len(effect.parameters)
        instances.append(effect(*[vector[k + j] for j in range(count)]))
        k += count
    pressure, radius, length, deflection = batch_arrays
    model = TubeModel(law, effects=tuple(instances), reference=(reference[0], reference[1]))
    prediction = rig.predict(model, pressure, radius, length, deflection)
    return prediction.force, prediction


def _residual_fn(vector, reference, batch_arrays, target, scale, prior_mean, prior_sd, *, rig,
                 scaling, effects=()):
    force, prediction = _model_forces(vector, reference, batch_arrays, rig=rig,
                                      scaling=scaling, effects=effects)
    residual = (scale * (force - target)).reshape(-1)
    prior = (vector - prior_mean) / prior_sd  # inf sd -> 0 (no prior)
    return jnp.concatenate([residual, prior]), prediction


@partial(jt.stored_jit, static_argnames=("rig", "scaling", "effects"))
def _residuals_and_jacobian(vector, *args, rig, scaling, effects=()):
    """Residuals and their Jacobian w.r.t. the whole coordinate vector (every coordinate:
    which are free is chosen on the host, so fits that free different coordinates share
    this compilation). Stored between runs by the command line (``jaxtube.stored_jit``)."""
    def fn(x):
        r, prediction = _residual_fn(x, *args, rig=rig, scaling=scaling, effects=effects)
        return r, (r, prediction)

    jacobian, (residual, prediction) = jax.jacfwd(fn, has_aux=True)(vector)
    return residual, jacobian, prediction


# --------------------------------------------------------------------------------------------
# The fit
# --------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class FitProblem:
    """Everything that defines the least-squares problem (built by :func:`fit`)."""

    data: MeasuredData
    batch: CurveBatch
    rig: CantileverRig
    scaling: PivotScaling
    reference: tuple[float, float]
    names: tuple[str, ...]
    free_index: tuple[int, ...]
    base: np.ndarray
    lower: np.ndarray  # [n_names] bounds of every coordinate (free or not)
    upper: np.ndarray
    prior_mean: np.ndarray  # [n_names] (sd inf: no prior)
    prior_sd: np.ndarray
    noise: float
    noise_given: bool
    effects: tuple = ()  # effect classes whose parameters follow the law's coordinates

    @property
    def free_names(self) -> list[str]:
        return [self.names[i] for i in self.free_index]

    @property
    def effect_names(self) -> tuple[str, ...]:
        """``effect.parameter`` names of the effects' coordinates (the law's are the rest)."""
        return tuple(f"{e.name}.{p.name}" for e in self.effects for p in e.parameters)

    @property
    def free_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        free = np.asarray(self.free_index)
        return self.lower[free], self.upper[free]

    def with_free(self, names, vector) -> FitProblem:
        """The same problem (same compiled model) with the coordinates ``names`` free and
        every other coordinate held at its value in the full ``vector``."""
        index = tuple(sorted(self.names.index(name) for name in set(names)))
        if not index:
            raise ValueError("nothing to fit: no free coordinates")
        return dataclasses.replace(self, free_index=index, base=np.array(vector, float))

    def batch_arrays(self):
        b = self.batch
        return (b.pressure, b.radius, b.length, b.deflection)

    def static(self):
        return dict(rig=self.rig, scaling=self.scaling, effects=self.effects)

    def full(self, free_values) -> np.ndarray:
        """The whole coordinate vector with ``free_values`` at the free positions."""
        vector = np.array(self.base, float)
        vector[np.asarray(self.free_index)] = free_values
        return vector

    def scale(self, robust_weight=None):
        w = self.batch.weight * (1.0 if robust_weight is None else robust_weight)
        return np.sqrt(w) / self.noise

    def residual_args(self, robust_weight=None):
        return (np.asarray(self.reference), self.batch_arrays(), self.batch.force,
                self.scale(robust_weight), self.prior_mean, self.prior_sd)


def make_problem(data: MeasuredData, scaling: PivotScaling | None = None,
                 rig: CantileverRig | None = None, options: FitOptions | None = None,
                 initial: np.ndarray | None = None, effects: tuple = ()) -> FitProblem:
    """Set up the least-squares problem: layout, first guess, fixed values, bounds, priors.

    ``effects``: :class:`fitting.Effect` subclasses whose parameters are fitted too (named
    ``effect.parameter``, starting at their null values, within their bounds); the rig gets
    the degrees of freedom they need.
    """
    scaling = scaling or PivotScaling()
    rig = rig or CantileverRig()
    options = options or FitOptions()
    effects = tuple(effects)
    features = frozenset(rig.features).union(*[e.features for e in effects])
    rig = dataclasses.replace(rig, features=features)
    batch = batch_curves(data)
    reference = reference_specimen(data)
    effect_parameters = [(e, p) for e in effects for p in e.parameters]
    names = tuple(scaling.names()) + tuple(f"{e.name}.{p.name}" for e, p in effect_parameters)
    law_vector = initial_vector(data, scaling) if initial is None else initial
    base = np.concatenate([np.asarray(law_vector, float),
                           [p.null for _, p in effect_parameters]])
    known = set(names)
    for table in (options.fixed, options.priors, options.bounds):
        unknown = sorted(set(table) - known)
        if unknown:
            raise ValueError(f"unknown parameter name(s) {unknown}; the fitted coordinates "
                             f"are {', '.join(names)}")
    for name, bound in options.bounds.items():
        if name.endswith(".A"):
            raise ValueError(f"{name}: bounds apply to exponents; constrain A by a prior")
        if not bound[0] < bound[1]:
            raise ValueError(f"{name}: bounds must satisfy low < high, got {bound}")
    lower = np.full(len(names), -np.inf)
    upper = np.full(len(names), np.inf)
    prior_mean = np.zeros(len(names))
    prior_sd = np.full(len(names), np.inf)
    effect_bounds = {f"{e.name}.{p.name}": (p.lower, p.upper) for e, p in effect_parameters}
    for i, name in enumerate(names):
        if name in effect_bounds:
            lower[i], upper[i] = options.bounds.get(name, effect_bounds[name])
        elif not name.endswith(".A"):
            lower[i], upper[i] = options.bounds.get(name, EXPONENT_BOUNDS)
        else:
            lower[i] = base[i] - math.log(SCALE_RANGE)
            upper[i] = base[i] + math.log(SCALE_RANGE)
        if name in options.priors:
            prior = options.priors[name]
            if not prior.sd > 0:
                raise ValueError(f"{name}: a prior needs sd > 0, got {prior.sd}")
            prior_mean[i], prior_sd[i] = prior.mean, prior.sd
    # Fixed exponents first, then fixed A values (which need the exponents to convert).
    exponent_of = {}
    for name, value in options.fixed.items():
        if not name.endswith(".A"):
            base[names.index(name)] = float(value)
    for name in names:
        if name.endswith(".A") and name not in effect_bounds:
            exponent_of[name] = [names.index(name[:-1] + e) for e in scaling.exponents]
    log_reference = _log_reference(scaling, reference)
    for name, value in options.fixed.items():
        if name.endswith(".A"):
            if not value > 0:
                raise ValueError(f"{name}: A must be > 0, got {value}")
            exps = base[exponent_of[name]]
            base[names.index(name)] = math.log(value) + float(np.dot(exps, log_reference))
    for name, prior in options.priors.items():
        if name.endswith(".A"):
            i = names.index(name)
            if not prior.mean > 0:
                raise ValueError(f"{name}: the prior mean of A must be > 0, got {prior.mean}")
            # log a = log A + B log s_ref: the prior is on log A, centred with the guess's B.
            prior_mean[i] = math.log(prior.mean) + float(np.dot(base[exponent_of[name]],
                                                                 log_reference))
    free_index = tuple(i for i, name in enumerate(names) if name not in options.fixed)
    if not free_index:
        raise ValueError("every parameter is fixed: nothing to fit")
    noise = estimate_noise(data) if options.noise_N is None else float(options.noise_N)
    if not noise > 0:
        raise ValueError(f"the force noise must be > 0 [N], got {noise}")
    return FitProblem(
        data=data, batch=batch, rig=rig, scaling=scaling, reference=reference, names=names,
        free_index=free_index, base=base, lower=lower, upper=upper,
        prior_mean=prior_mean, prior_sd=prior_sd, noise=noise,
        noise_given=options.noise_N is not None, effects=effects)


def _log_reference(scaling: PivotScaling, reference) -> np.ndarray:
    p_ref, r_ref = reference
    if scaling.form == "paper":
        return np.array([math.log(p_ref * r_ref**3)])
    return np.array([math.log(p_ref), math.log(r_ref)])


def _huber_weight(residual, threshold):
    a = np.abs(residual)
    return np.where(a <= threshold, 1.0, threshold / np.maximum(a, 1e-300))


def _levenberg_marquardt(problem: FitProblem, x0: np.ndarray, options: FitOptions, bar=None):
    """One LM run from ``x0`` (free coordinates). Returns ``(x, cost, report dict)``."""
    static = problem.static()
    n_data = problem.batch.force.size
    robust = None
    counts = {"residual": 0, "jacobian": 0}

    def evaluate(x):
        # Residuals and Jacobian always come together: one compiled function (compile time
        # dominates a fit), and the forward-mode Jacobian costs little more than the solves.
        counts["jacobian"] += 1
        r, jac, pred = _residuals_and_jacobian(jnp.asarray(problem.full(x)),
                                               *problem.residual_args(robust), **static)
        full = np.asarray(jac)  # every coordinate's column (score tests, diagnosis)
        return np.asarray(r), full[:, np.asarray(problem.free_index)], pred, full

    def ok(r, jac, pred):
        return (bool(np.all(np.asarray(pred.converged)[problem.batch.mask]))
                and bool(np.all(np.isfinite(r))) and bool(np.all(np.isfinite(jac))))

    lower, upper = problem.free_bounds
    x = np.clip(np.asarray(x0, float), lower, upper)
    r, jac, pred, full = evaluate(x)
    if not ok(r, jac, pred):
        bad = int(np.sum(~np.asarray(pred.converged)[problem.batch.mask]))
        raise FitError(f"the equilibrium solves failed at the initial guess ({bad} points did "
                       "not converge); check the data units (bar, mm, m, N)")
    def reweighted(x, r, jac, pred, full):
        # Huber loss by iteratively reweighted least squares: weights from these residuals.
        nonlocal robust
        if options.loss != "huber":
            return r, jac, pred, full
        robust = _huber_weight(r[:n_data].reshape(problem.batch.force.shape),
                               options.huber_threshold)
        return evaluate(x)

    r, jac, pred, full = reweighted(x, r, jac, pred, full)
    cost = 0.5 * float(r @ r)
    jtj = jac.T @ jac
    mu = 1e-3  # dimensionless: the damping term is mu * diag(J^T J) (Marquardt scaling)
    nu = 2.0
    outcome = FitOutcome.iterations_exhausted
    iteration = 0
    history = [2.0 * cost]  # chi^2 after each accepted iteration (stagnation rule)
    watched = (np.isin(problem.free_names, options.stop_on_bound) if options.stop_on_bound
               else None)
    on_bound_rule = np.isin(problem.free_names, problem.effect_names)
    for iteration in range(1, options.max_iterations + 1):
        g = jac.T @ r
        # Active set: an effect's coordinate on a bound whose descent direction points out of
        # the box is held for this step (Voglis & Lagaris 2004, the "dogbox" rule). Solving
        # for it and clipping afterwards would leave the other coordinates with a step
        # computed as if it moved: rejected again and again at a null on a bound, one
        # evaluation each. The law's coordinates keep the clipped step (holding them too moved
        # the diagnosis' stopping points by ~0.1 in chi^2: README "Hidden-effect designs").
        active = on_bound_rule & (((x <= lower) & (g > 0)) | ((x >= upper) & (g < 0)))
        free = ~active
        if watched is not None and watched.any() and bool(np.all(active[watched])):
            outcome = FitOutcome.back_on_bound
            break
        g_free = np.where(free, g, 0.0)
        if float(np.max(np.abs(g_free))) <= options.gtol * max(1.0, cost):
            outcome = FitOutcome.gradient_small
            break
        diag = np.maximum(np.diag(jtj), 1e-12 * max(float(np.max(np.diag(jtj))), 1e-300))
        accepted = False
        while not accepted:
            step = np.zeros_like(x)
            step[free] = np.linalg.solve(jtj[np.ix_(free, free)] + mu * np.diag(diag[free]),
                                         -g[free])
            x_new = np.clip(x + step, lower, upper)
            step = x_new - x
            predicted = -(g @ step + 0.5 * step @ (jtj @ step))
            r_new, jac_new, pred_new, full_new = evaluate(x_new)
            if ok(r_new, jac_new, pred_new) and predicted > 0:
                cost_new = 0.5 * float(r_new @ r_new)
                rho = (cost - cost_new) / predicted
            else:
                cost_new, rho = math.inf, -1.0
            if rho > 0:
                accepted = True
                mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
            else:
                mu *= nu
                nu *= 2.0
                if not mu < 1e16:
                    break
        if not accepted:
            outcome = FitOutcome.damping_exhausted
            break
        relative_change = (cost - cost_new) / max(cost, 1e-300)
        cost_before = cost
        small_step = float(np.max(np.abs(step))) <= 1e-10 * (1.0 + float(np.max(np.abs(x))))
        x = x_new
        r, jac, pred, full = reweighted(x, r_new, jac_new, pred_new, full_new)
        cost = 0.5 * float(r @ r)
        jtj = jac.T @ jac
        if bar is not None:
            bar.update(1)
            bar.set_postfix(rmse_N=f"{_rmse(problem, pred):.4g}", damping=f"{mu:.1e}")
        # The loss is chi^2 / 2 in noise units: a decrease of 1e-3 is statistically nothing
        # (it also ends slow drifts along directions the data do not determine).
        negligible = 2.0 * (cost_before - cost) <= options.chi2_tol
        if relative_change <= options.ftol or small_step or negligible:
            outcome = (FitOutcome.step_small if small_step else FitOutcome.decrease_small)
            break
        history.append(2.0 * cost)
        window = options.stall_window
        if len(history) > window and history[-window - 1] - history[-1] < options.stall_chi2:
            outcome = FitOutcome.stagnated
            break
    message, converged = ending(outcome)
    return x, cost, dict(message=message, converged=converged, iterations=iteration,
                         evaluations=counts["jacobian"],
                         r=r, jac=jac, full_jacobian=full, prediction=pred, robust=robust)


def _rmse(problem: FitProblem, prediction) -> float:
    mask = problem.batch.mask
    err = (np.asarray(prediction.force) - problem.batch.force)[mask]
    return float(np.sqrt(np.mean(err**2)))


def forces_and_sensitivity(problem: FitProblem, free_values, batch_arrays):
    """Model forces ``[C, P]`` [N], ``dF/dtheta`` ``[C, P, n_free]`` and per-point
    convergence at specimens ``batch_arrays`` (:func:`specimen_arrays`).

    Runs the fit's own compiled residual-and-Jacobian function with unit scale and zero
    targets, so arrays of the fitted data's shape need no new compilation.
    """
    shape = np.shape(batch_arrays[3])
    args = (np.asarray(problem.reference), batch_arrays, np.zeros(shape), np.ones(shape),
            problem.prior_mean, problem.prior_sd)
    r, jac, pred = _residuals_and_jacobian(jnp.asarray(problem.full(free_values)), *args,
                                           **problem.static())
    n = int(np.prod(shape))
    jac = np.asarray(jac[:n])[:, np.asarray(problem.free_index)]
    return (np.asarray(r[:n]).reshape(shape), jac.reshape(shape + (-1,)),
            np.asarray(pred.converged))


def specimen_arrays(pressure: Sequence[float], radius: Sequence[float],
                    length: Sequence[float], deflection) -> tuple:
    """Batch arrays for predictions at arbitrary specimens (deflection ``[C, P]`` [m])."""
    return (np.asarray(pressure, float), np.asarray(radius, float), np.asarray(length, float),
            np.asarray(deflection, float))


__all__ = ["FitError", "FitOptions", "Prior", "Convergence", "estimate_noise", "make_problem",
           "unpad"]
