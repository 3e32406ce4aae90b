"""A campaign's model values fitted to its calibration cases by gradient, with standard
errors and a statement for every value the cases do not determine.

**Objective.** The mean over the calibration cases of the squared smooth marker RMS
(:func:`fitting.smooth_shape_score`: the peers' metric with the radius continuous along each
tube, re-registered at every evaluation: the first by the full search of
:func:`fitting.register`, every later one iterated from the case's last registration), in
mm², as a function of the fitted values' search coordinates
(:func:`fitting.search_coordinates`: the logarithm of a factor such as ``"bending_scale"``
or ``"rest_length_factors.SET"``; a mass or an offset such as ``"point_masses_kg.POINT"`` or
``"pressure_offset_bar"`` as it is). Its gradient is each case's position gradient at the
optimal registration times the equilibrium's tangents (:meth:`fitting.CaseSolver.tangents`:
implicit function theorem). Search: Gauss-Newton on the markers' distances in a trust
region (Moré 1978; Nocedal & Wright 2006, ch. 4 and 10), the registrations' six numbers per
case projected out of each step and solved again at every trial (variable projection), each
step clipped to the values' bounds. The region is a ball in the search coordinates (a unit
per factor's logarithm, a quarter of its bounds per mass or offset), of radius
``INITIAL_RADIUS`` at first; it shrinks to a quarter of the step where the fall of the mean
square RMS is under a quarter of the linear model's prediction and doubles where it is over
three quarters at the boundary, so a far trial is not solved again and again. It stops when
a step lowers the root of the objective by less than ``RMS_TOLERANCE_MM`` or moves the
coordinates by less than 1e-5, or when the radius falls below ``MIN_RADIUS`` (a minimum,
unless a case did not converge at the last trial: then the fit is reported not converged).
Every evaluation solves each case from its last equilibrium (:class:`fitting.CaseSolver`
``warm_starts``), the cases in threads (``threads``).

**Standard errors** (Gauss-Newton at the optimum): the residuals are the tube markers'
smooth surface distances of every case; their Jacobian has a column per fitted value
(distances' position gradient times the tangents) and six per case for that case's rigid
registration (a nuisance parameter, so the values' uncertainty includes it). With ``s²``
the residuals' sum of squares over ``M - k - 6 C`` degrees of freedom, the covariance is
``s² (JᵀJ)⁻¹`` and the values' block gives their standard errors in search coordinates (a
relative error of a factor; a mass's or an offset's own).

**Not determined**: a factor whose relative standard error exceeds
``UNDETERMINED_RELATIVE_ERROR`` (the cases cannot tell it within a factor of about 1.6), a
mass or an offset whose standard error exceeds that fraction of its bounds' width, or a
value that sits at one of its bounds, is said to be so; two values whose estimates correlate
beyond ``UNSEPARATED_CORRELATION`` are said not to be separated by the cases.
"""

from __future__ import annotations

import dataclasses
import os
import time
from concurrent.futures import ThreadPoolExecutor

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._shape.markers import load_markers
from .._shape.smooth import continuous_radius, smooth_shape_score
from .._shape.surfaces import tube_surface_distance
from .file import Campaign
from .kite import (
    campaign_tube_surfaces,
    is_offset,
    model_value,
    search_coordinates,
    values_from_search,
    with_values,
)
from .model import KiteModel
from .solve import CaseSolver

#: The search stops when a step lowers the root of the mean square RMS by less than this
#: [mm]: far below what photogrammetric markers resolve.
RMS_TOLERANCE_MM = 0.01
#: The search's first trust radius and the one below which it gives up, in scaled search
#: coordinates (:func:`_search_scale`: 0.7 is a factor of 2 on one value).
INITIAL_RADIUS = 0.7
MIN_RADIUS = 1e-4
UNDETERMINED_RELATIVE_ERROR = 0.5
UNSEPARATED_CORRELATION = 0.99
#: Plausible bounds of each kind of value (factors on the model file's values).
DEFAULT_BOUNDS = {"bending_scale": (0.05, 5.0), "torsion_scale": (0.1, 10.0),
                  "collapse_scale": (0.1, 10.0),
                  "pressure_factor": (0.8, 1.25), "rest_length_factors": (0.8, 1.2),
                  "stiffness_factors": (0.1, 10.0), "bending_class_factors": (0.05, 20.0),
                  "pressure_offset_bar": (-0.05, 0.05), "point_masses_kg": (0.0, 5.0),
                  "suspension_offsets_mm": (-200.0, 200.0)}


@dataclasses.dataclass(frozen=True)
class CampaignCalibration:
    """A calibration's outcome.

    Attributes:
        model: the fitted model.
        names: the fitted values; values: ``[k]`` their fitted values.
        standard_errors: ``[k]`` their standard errors (same units; ``nan`` if singular).
        correlation: ``[k, k]`` correlation of the estimates (log values).
        statements: what the cases do not determine, in words (empty: every value is).
        rms_mm_before, rms_mm_after: ``{case: smooth RMS [mm]}`` at the start and the end.
        converged: the search met its tolerance; message: its message.
        evaluations: objective evaluations.
        residual_sum_squares_m2: the tube markers' smooth distances' sum of squares [m²]
            over every case at the end; residual_count: how many; degrees_of_freedom: that
            count less the values and six registration numbers per case.
        least_squares: at the end, ``(jacobian [M, k + 6 C], residual [M] [m], {case: (first
            row, last row + 1)})``: the tube markers' smooth distances of every case and
            their Jacobian in the values' search coordinates and each case's registration
            (module docstring; :func:`fitting.diagnose_campaign` scores left-out cases from
            it).
        registrations: ``{case: fitting.Registration}`` of each case at the end (a later
            fit of the same cases starts from them: ``calibrate_campaign(registrations=)``).
    """

    model: KiteModel
    names: tuple
    values: np.ndarray
    standard_errors: np.ndarray
    correlation: np.ndarray
    statements: tuple
    rms_mm_before: dict
    rms_mm_after: dict
    converged: bool
    message: str
    evaluations: int
    residual_sum_squares_m2: float
    residual_count: int
    degrees_of_freedom: int
    least_squares: tuple = dataclasses.field(default=(), repr=False, compare=False)
    registrations: dict = dataclasses.field(default_factory=dict, repr=False, compare=False)

    def to_json(self) -> dict:
        """The model file's content (``model``) with the estimates and what was said."""
        error = [None if not np.isfinite(e) else float(e) for e in self.standard_errors]
        return {"model": self.model.to_json(),
                "fitted": {n: {"value": float(v), "standard_error": e}
                           for n, v, e in zip(self.names, self.values, error)},
                "statements": list(self.statements), "converged": self.converged,
                "message": self.message, "evaluations": self.evaluations,
                "rms_mm_before": self.rms_mm_before, "rms_mm_after": self.rms_mm_after}


def value_bounds(name: str) -> tuple:
    """The plausible bounds of value ``name`` (:data:`DEFAULT_BOUNDS` by its kind)."""
    return DEFAULT_BOUNDS[name.partition(".")[0]]


def on_bound(name: str, value: float, bounds: tuple) -> bool:
    """``value`` of ``name`` sits on an edge of ``bounds`` ``(low, high)``: within 1e-3 of
    it in search coordinates (relative for a factor, of the bounds' width for an offset)."""
    coordinates = search_coordinates((name,) * 3, (value, *bounds))
    scale = bounds[1] - bounds[0] if is_offset(name) else 1.0
    return min(abs(coordinates[0] - coordinates[1]),
               abs(coordinates[0] - coordinates[2])) < 1e-3 * scale


def calibrate_campaign(campaign: Campaign, model: KiteModel, names, cases,
                       solver: CaseSolver, bounds=None, max_steps: int = 20,
                       log=print, threads: int | None = None,
                       registrations=None) -> CampaignCalibration:
    """Fit ``model``'s values ``names`` to ``cases`` (names, each with markers), starting
    from ``model`` (module docstring). ``bounds``: ``{name: (low, high)}`` (default
    :func:`value_bounds`); ``threads``: cases solved at once in an evaluation (default one
    per core, at most one per case: each solve is a compiled program on one core);
    ``registrations``: ``{case: fitting.Registration}`` each case's first registration is
    iterated from (a previous fit's ``registrations``, near this start; default: the full
    search of :func:`fitting.register`)."""
    threads = threads or max(1, min(len(cases), os.cpu_count() or 1))
    names = tuple(names)
    bounds = {n: (bounds or {}).get(n, value_bounds(n)) for n in names}
    low = search_coordinates(names, [bounds[n][0] for n in names])
    high = search_coordinates(names, [bounds[n][1] for n in names])
    markers = {c: load_markers(campaign.case(c).markers) for c in cases}
    evaluations = []
    # each case's last registration: the next one starts from it
    registrations = dict(registrations or {})

    seconds = {}  # each case's last solve and score: the longest start first

    def solved(case, current):
        """``(positions, tangents, score)`` of ``case`` with ``current`` (None: no
        equilibrium)."""
        started = time.perf_counter()
        positions, tangents, converged = solver.tangents(campaign.case(case), current, names)
        score = None if not converged else smooth_shape_score(
            campaign_tube_surfaces(campaign, positions), markers[case],
            canopy_group=campaign.canopy_group, start=registrations.get(case))
        seconds[case] = time.perf_counter() - started
        return None if score is None else (positions, tangents, score)

    def evaluate(theta):
        values = values_from_search(names, theta)
        current = with_values(model, names, values)
        order = sorted(cases, key=lambda case: -seconds.get(case, 0.0))
        with ThreadPoolExecutor(threads) as pool:  # compiled programs release the GIL
            done = dict(zip(order, pool.map(lambda case: solved(case, current), order)))
        states = {case: done[case] for case in cases}
        if any(state is None for state in states.values()):
            return None
        for case, state in states.items():
            registrations[case] = state[2].registration.registration
        per_case = {case: state[2].rms_mm for case, state in states.items()}
        total = float(np.mean(np.square(list(per_case.values()))))
        evaluations.append((theta.copy(), total, per_case, states))
        log(f"{', '.join(f'{n} {v:.4f}' for n, v in zip(names, values))}: mean square RMS "
            f"{total:.1f} mm^2 ({', '.join(f'{c} {r:.1f}' for c, r in per_case.items())})")
        return evaluations[-1]

    current = evaluate(np.clip(search_coordinates(names, [model_value(model, n)
                                                         for n in names]), low, high))
    if current is None:
        raise RuntimeError(f"calibrate: a case does not converge at the start ({model})")
    scale = _search_scale(names, bounds)
    radius, converged, message = INITIAL_RADIUS, False, f"stopped after {max_steps} steps"
    for _ in range(max_steps):
        theta, total, _, states = current
        jacobian, residual, _ = _least_squares_system(campaign, markers, states, len(names),
                                                      per_case_weight=True)
        reduced = _projected_system(jacobian, residual, len(names))
        trial, unsolved = None, False
        while radius > MIN_RADIUS:
            candidate = np.clip(theta + _trust_region_step(*reduced, scale, radius), low, high)
            length = float(np.linalg.norm((candidate - theta) / scale))
            if length == 0.0:
                break
            predicted = 1e6 * _predicted_fall(*reduced, candidate - theta)  # mm^2
            trial = evaluate(candidate)
            unsolved = trial is None
            actual = -np.inf if unsolved else total - trial[1]
            ratio = actual / predicted if predicted > 0 else -np.inf
            if ratio < 0.25:
                radius = 0.25 * length
            elif ratio > 0.75 and length > 0.9 * radius:
                radius = 2.0 * radius
            if actual > 0:
                break
            trial = None
        if trial is None and unsolved:
            message = ("the trust region shrank below its smallest radius with a case that "
                       "does not converge at the last trial: no minimum established")
            break
        if trial is None:
            converged, message = True, ("no step within the trust region lowers the RMS: a "
                                        "minimum")
            break
        moved = np.max(np.abs(trial[0] - theta))
        current = trial
        fall = np.sqrt(total) - np.sqrt(trial[1])
        if fall < RMS_TOLERANCE_MM or moved < 1e-5:
            converged, message = True, (f"the RMS fell by {fall:.2g} mm (< "
                                        f"{RMS_TOLERANCE_MM} mm) or the values moved by "
                                        f"{moved:.2g} (log)")
            break
    theta, _, per_case, states = current
    values = values_from_search(names, theta)
    jacobian, residual, rows = _least_squares_system(campaign, markers, states, len(names))
    search_errors, correlation, residuals = _search_standard_errors(jacobian, residual,
                                                                    len(names))
    errors = np.asarray([e if is_offset(n) else v * e
                         for n, v, e in zip(names, values, search_errors)])
    statements = []
    for k, name in enumerate(names):
        width = bounds[name][1] - bounds[name][0] if is_offset(name) else 1.0
        if not np.isfinite(search_errors[k]) or \
                search_errors[k] > UNDETERMINED_RELATIVE_ERROR * width:
            size = (f"standard error {errors[k]:.2g} against bounds {list(bounds[name])}"
                    if is_offset(name) else f"relative standard error {search_errors[k]:.2g}")
            statements.append(f"{name} is not determined by the cases {', '.join(cases)} "
                              f"({size})")
        elif on_bound(name, values[k], bounds[name]):
            statements.append(f"{name} = {values[k]:.4g} sits at a bound of its plausible "
                              f"range {list(bounds[name])}")
        for j in range(k):
            if abs(correlation[k, j]) > UNSEPARATED_CORRELATION:
                statements.append(f"{names[j]} and {name} are not separated by the cases "
                                  f"(correlation {correlation[k, j]:.3f})")
    return CampaignCalibration(with_values(model, names, values), names, values,
                               errors, correlation, tuple(statements),
                               evaluations[0][2], per_case, converged, message,
                               len(evaluations), *residuals, (jacobian, residual, rows),
                               {case: state[2].registration.registration
                                for case, state in states.items()})


@eqx.filter_jit
def _distances_and_jacobians(surfaces, registration, points, point_groups, positions):
    """The tube markers' smooth surface distances ``[m]`` [m] at node ``positions`` [N, 3]
    and their Jacobians with respect to the positions, the registration's rotation vector
    and its translation (reverse mode: one pass per tube marker, tens, rather than per
    coordinate, hundreds); compiled once per case's marker count."""

    def distances(x, rotation, translation):
        moved = eqx.tree_at(lambda r: (r.rotation_vector, r.translation), registration,
                            (rotation, translation))
        return tube_surface_distance(surfaces.with_positions(x), moved.apply(points),
                                     point_groups)[0]

    arguments = (positions, registration.rotation_vector, registration.translation)
    return distances(*arguments), jax.jacrev(distances, argnums=(0, 1, 2))(*arguments)


def _least_squares_system(campaign, markers, states, k, per_case_weight=False):
    """``(jacobian [M, k + 6 C], residual [M], {case: (first row, last row + 1)})`` of the
    tube markers' smooth distances [m] of every case: columns for the ``k`` values' search
    coordinates (distances' position gradient times the equilibrium's tangents), then six
    per case for its registration (rotation vector, translation). ``per_case_weight``: each
    case's rows divided by ``sqrt(m_c C)`` (then the sum of squares is the mean over cases
    of the squared RMS)."""
    blocks, residuals = [], []
    for case, (positions, tangents, score) in states.items():
        surfaces = continuous_radius(campaign_tube_surfaces(campaign, positions))
        registration = score.registration.registration
        groups = registration.surface_groups(markers[case], surfaces)
        tube = np.flatnonzero(groups >= 0)
        points = markers[case].position[tube]
        distance, (by_position, by_rotation, by_translation) = _distances_and_jacobians(
            surfaces, registration, points, jnp.asarray(groups[tube]), jnp.asarray(positions))
        residuals.append(np.asarray(distance))
        by_value = np.einsum("mnd,ndk->mk", np.asarray(by_position), tangents)
        blocks.append((by_value, np.concatenate([np.asarray(by_rotation),
                                                 np.asarray(by_translation)], 1)))
    count = sum(len(r) for r in residuals)
    jacobian = np.zeros((count, k + 6 * len(blocks)))
    row, rows = 0, {}
    for c, (case, (by_value, by_registration)) in enumerate(zip(states, blocks)):
        rows[case] = (row, row + len(by_value))
        weight = 1.0 / np.sqrt(len(by_value) * len(blocks)) if per_case_weight else 1.0
        jacobian[row:row + len(by_value), :k] = weight * by_value
        jacobian[row:row + len(by_value), k + 6 * c:k + 6 * c + 6] = weight * by_registration
        residuals[c] = weight * residuals[c]
        row += len(by_value)
    return jacobian, np.concatenate(residuals), rows


def _search_scale(names, bounds) -> np.ndarray:
    """``[k]`` the unit of each search coordinate in the trust region's norm: 1 for a
    factor's logarithm, a quarter of its bounds' width for a mass or an offset."""
    return np.asarray([(bounds[n][1] - bounds[n][0]) / 4 if is_offset(n) else 1.0
                       for n in names])


def _projected_system(jacobian, residual, k):
    """``(values' Jacobian [M, k], residual [M])`` with the registrations projected out
    (variable projection: every trial registers each case again, so a step of the values is
    judged with the registrations' best linear response)."""
    registration = jacobian[:, k:]
    basis, singular, _ = np.linalg.svd(registration, full_matrices=False)
    basis = basis[:, singular > singular[0] * 1e-12] if singular.size else basis[:, :0]

    def project(x):
        return x - basis @ (basis.T @ x)

    return project(jacobian[:, :k]), project(residual)


def _trust_region_step(values_jacobian, residual, scale, radius):
    """``[k]`` the Gauss-Newton step of the values, or where it is longer than ``radius``
    (norm of the step over ``scale``) the Levenberg step of that length (Moré 1978: the
    damping found by bisection of its logarithm)."""
    scaled = values_jacobian * scale[None, :]
    step = -np.linalg.lstsq(scaled, residual, rcond=None)[0]
    if np.linalg.norm(step) <= radius:
        return step * scale
    normal, gradient = scaled.T @ scaled, scaled.T @ residual
    low, high = -30.0, np.log10(max(np.linalg.norm(gradient) / radius, 1e-300))
    for _ in range(60):  # ||step(damping)|| decreases with the damping
        middle = 0.5 * (low + high)
        step = -np.linalg.solve(normal + 10.0 ** middle * np.eye(len(scale)), gradient)
        low, high = (middle, high) if np.linalg.norm(step) > radius else (low, middle)
    return -np.linalg.solve(normal + 10.0 ** high * np.eye(len(scale)), gradient) * scale


def _predicted_fall(values_jacobian, residual, step):
    """The fall of the residuals' sum of squares the linear model predicts for ``step``."""
    after = residual + values_jacobian @ step
    return float(residual @ residual - after @ after)


def _search_standard_errors(jacobian, residual, k):
    """Standard errors of the values in search coordinates, their correlation (Gauss-Newton
    over the markers' smooth distances ``residual`` with ``jacobian``: each case's
    registration a nuisance parameter) and ``(sum of squares [m²], residual count, degrees
    of freedom)``."""
    count, columns = jacobian.shape
    squares = float(residual @ residual)
    residuals = (squares, count, count - columns)
    variance = squares / max(count - columns, 1)
    normal = jacobian.T @ jacobian
    if np.linalg.cond(normal) > 1e14:
        return np.full(k, np.nan), np.full((k, k), np.nan), residuals
    covariance = variance * np.linalg.inv(normal)[:k, :k]
    errors = np.sqrt(np.diag(covariance))
    return errors, covariance / np.outer(errors, errors), residuals
