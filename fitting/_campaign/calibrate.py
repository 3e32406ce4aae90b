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
implicit function theorem). Search: damped Gauss-Newton (Levenberg) on the markers'
distances, the registrations' six numbers per case in the step and solved again at every
trial (variable projection), each step clipped to the values' bounds; it stops when a step
lowers the root of the objective by less than ``RMS_TOLERANCE_MM`` or moves the coordinates
by less than 1e-5, or when no damping lowers it. Every evaluation solves each case from its
last equilibrium (:class:`fitting.CaseSolver` ``warm_starts``).

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
                       log=print) -> CampaignCalibration:
    """Fit ``model``'s values ``names`` to ``cases`` (names, each with markers), starting
    from ``model`` (module docstring). ``bounds``: ``{name: (low, high)}`` (default
    :func:`value_bounds`)."""
    names = tuple(names)
    bounds = {n: (bounds or {}).get(n, value_bounds(n)) for n in names}
    low = search_coordinates(names, [bounds[n][0] for n in names])
    high = search_coordinates(names, [bounds[n][1] for n in names])
    markers = {c: load_markers(campaign.case(c).markers) for c in cases}
    evaluations = []
    registrations = {}  # each case's last registration: the next one starts from it

    def evaluate(theta):
        values = values_from_search(names, theta)
        current = with_values(model, names, values)
        per_case, states = {}, {}
        for case in cases:
            positions, tangents, converged = solver.tangents(campaign.case(case), current,
                                                             names)
            if not converged:
                return None
            states[case] = (positions, tangents, smooth_shape_score(
                campaign_tube_surfaces(campaign, positions), markers[case],
                canopy_group=campaign.canopy_group, start=registrations.get(case)))
            registrations[case] = states[case][2].registration.registration
            per_case[case] = states[case][2].rms_mm
        total = float(np.mean(np.square(list(per_case.values()))))
        evaluations.append((theta.copy(), total, per_case, states))
        log(f"{', '.join(f'{n} {v:.4f}' for n, v in zip(names, values))}: mean square RMS "
            f"{total:.1f} mm^2 ({', '.join(f'{c} {r:.1f}' for c, r in per_case.items())})")
        return evaluations[-1]

    current = evaluate(np.clip(search_coordinates(names, [model_value(model, n)
                                                         for n in names]), low, high))
    if current is None:
        raise RuntimeError(f"calibrate: a case does not converge at the start ({model})")
    damping, converged, message = 1e-3, False, f"stopped after {max_steps} steps"
    for _ in range(max_steps):
        theta, total, _, states = current
        jacobian, residual, _ = _least_squares_system(campaign, markers, states, len(names),
                                                      per_case_weight=True)
        normal = jacobian.T @ jacobian
        gradient = jacobian.T @ residual
        trial = None
        while damping < 1e8:
            step = -np.linalg.solve(normal + damping * np.diag(np.diag(normal)), gradient)
            candidate = np.clip(theta + step[:len(names)], low, high)
            trial = evaluate(candidate) if np.any(candidate != theta) else None
            if trial is not None and trial[1] < total:
                damping = max(damping / 3, 1e-9)
                break
            damping *= 4
            trial = None
        if trial is None:
            converged, message = True, "no damped Gauss-Newton step lowers the RMS: a minimum"
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
                               len(evaluations), *residuals, (jacobian, residual, rows))


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
