"""Rigid registration of measured markers onto a model's tube surfaces, and the marker RMS.

The markers are moved into the model frame by a rotation and a translation (no scale):
``x = R(rotation_vector) (p - marker_centroid) + translation``. The registration minimises
the RMS over the tube markers of the surface distance of
:func:`fitting._shape.surfaces.tube_surface_distance` (axis distance minus local radius,
markers matched by projection onto their group's axis, not by index): the peers' metric
(awegroup/Billow, ``docs/table_shape.tex``; squared, so its sign does not matter).

**Search** (:func:`register`, deterministic): for each spanwise order (both where the
markers have a spanwise family such as ``strut0 .. strut7``, see
:mod:`fitting._shape.markers`), starts from the centroid-and-principal-axes alignment of
the markers with the model's tube axes (the four proper sign choices of the axes), each also
turned by +-90 degrees about each principal axis (28 starts); from each,
Levenberg-Marquardt (Nielsen's damping, all starts in one batch, exact Jacobian by JAX, one
compiled ``lax.while_loop``) on ``R = exp([phi]x) R_start``, ``phi`` a rotation vector
starting at 0, so no start sits at the rotation vector's singularity. The least RMS over
all starts and orders wins, and is iterated on alone until its cost changes by less than
1e-14 relatively (or no damping gives a descent step): ``converged``.

**Gradients** (:func:`marker_rms`): with the registration ``g*(x)`` optimal for node
positions ``x``, ``d/dx RMS(x, g*(x)) = dRMS/dx (x, g*)`` because ``dRMS/dg = 0`` at the
optimum (envelope theorem), so the registration is held fixed when differentiating; tests
check this against finite differences of the re-registered RMS.
"""

from __future__ import annotations

import dataclasses
import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from scipy.spatial.transform import Rotation

from jaxtube import rotation_matrix

from .markers import CANOPY_GROUP, MarkerSet, marker_surface_groups, spanwise_family
from .surfaces import TubeSurfaces, canopy_distance, tube_surface_distance


class Registration(eqx.Module):
    """A rigid motion of the markers into the model frame, and the group matching.

    Attributes:
        rotation_vector: ``[3]`` rotation [rad] (axis times angle).
        translation: ``[3]`` where the marker centroid lands [m].
        marker_centroid: ``[3]`` the pivot of the rotation, in the measurement frame [m].
        spanwise_groups: the spanwise family whose order may be reversed (static).
        reversed_order: compare ``spanwise_groups[j]`` with the model's
            ``spanwise_groups[k-1-j]`` (static).
        canopy_group: the marker group compared with the canopy (static).
    """

    rotation_vector: Array
    translation: Array
    marker_centroid: Array
    spanwise_groups: tuple[str, ...] = eqx.field(static=True, default=())
    reversed_order: bool = eqx.field(static=True, default=False)
    canopy_group: str = eqx.field(static=True, default=CANOPY_GROUP)

    def apply(self, points: Array) -> Array:
        """``[m, 3]`` measured points -> ``[m, 3]`` model-frame points [m]."""
        rotation = rotation_matrix(self.rotation_vector)
        return (points - self.marker_centroid) @ rotation.T + self.translation

    def surface_groups(self, markers: MarkerSet, surfaces: TubeSurfaces) -> np.ndarray:
        """``[m]`` the model tube group of each marker (-1: canopy)."""
        return marker_surface_groups(markers, surfaces, spanwise_groups=self.spanwise_groups,
                                     reversed_order=self.reversed_order,
                                     canopy_group=self.canopy_group)


class MarkerDistances(eqx.Module):
    """Per-marker comparison with the model (arrays ``[m]`` unless said).

    Attributes:
        registered: ``[m, 3]`` markers in the model frame [m].
        distance: surface distance [m]: signed for tube markers (axis distance minus local
            radius), unsigned to the nearest canopy triangle for canopy markers (NaN where
            the model has no canopy).
        surface_group: model tube group index (-1: canopy).
        segment: nearest axis segment (tube markers; meaningless for canopy markers).
    """

    registered: Array
    distance: Array
    surface_group: Array
    segment: Array


@eqx.filter_jit
def marker_distances(surfaces: TubeSurfaces, markers: MarkerSet,
                     registration: Registration) -> MarkerDistances:
    """Distances of every marker to the model's surfaces under ``registration``."""
    groups = registration.surface_groups(markers, surfaces)
    registered = registration.apply(markers.position)
    distance, segment, _ = tube_surface_distance(surfaces, registered,
                                                 jnp.asarray(np.maximum(groups, 0)))
    canopy = groups < 0
    if canopy.any():
        on_canopy = canopy_distance(surfaces, registered) if surfaces.has_canopy else \
            jnp.full(len(groups), jnp.nan)
        distance = jnp.where(jnp.asarray(canopy), on_canopy, distance)
    return MarkerDistances(registered, distance, jnp.asarray(groups), segment)


@eqx.filter_jit
def marker_rms(surfaces: TubeSurfaces, markers: MarkerSet, registration: Registration) -> Array:
    """RMS [m] over the tube markers (not the canopy) of the surface distance: the peers'
    metric. Differentiable w.r.t. ``surfaces.node_positions`` and radii, and the registration
    (hold the registration fixed at its optimum for the total derivative: module docstring)."""
    groups = registration.surface_groups(markers, surfaces)
    tube = np.flatnonzero(groups >= 0)
    registered = registration.apply(markers.position[tube])
    distance, _, _ = tube_surface_distance(surfaces, registered, jnp.asarray(groups[tube]))
    return jnp.sqrt(jnp.mean(distance * distance))


@dataclasses.dataclass(frozen=True)
class RegistrationResult:
    """Outcome of :func:`register`.

    Attributes:
        registration: the best rigid motion and group matching.
        rms_m: its RMS [m] over the tube markers.
        rms_by_order: best RMS [m] per spanwise order tried (``False``: as numbered); for
            an order whose starts were all pruned, the best RMS when they were.
        starts: number of starts tried, all orders together.
        converged: the winning start, iterated alone, met its tolerance.
        message: ``converged`` or ``iteration limit reached``.
    """

    registration: Registration
    rms_m: float
    rms_by_order: dict
    starts: int
    converged: bool
    message: str


def _moved_distances(parameters, start_rotation, surfaces, points, groups, weights):
    """Weighted surface distances [m] of centred points ``[m, 3]`` moved by
    ``exp([phi]x) R_start`` and translated; ``parameters = [phi, translation]``."""
    rotation = rotation_matrix(parameters[:3]) @ start_rotation
    moved = points @ rotation.T + parameters[3:]
    return tube_surface_distance(surfaces, moved, groups)[0] * weights


def _with_jacobian(parameters, start_rotation, surfaces, points, groups, weights):
    residual = functools.partial(_moved_distances, start_rotation=start_rotation,
                                 surfaces=surfaces, points=points, groups=groups,
                                 weights=weights)
    return residual(parameters), jax.jacfwd(residual)(parameters)


_batched = jax.vmap(_with_jacobian, in_axes=(0, 0, None, None, 0, None))


@eqx.filter_jit
def _batched_levenberg_marquardt(parameters: Array, stopped: Array, iterations: Array,
                                 tolerance: Array, prune_after: Array, start_rotation: Array,
                                 surfaces: TubeSurfaces, points: Array, groups: Array,
                                 weights: Array):
    """Levenberg-Marquardt (Nielsen's damping update) on ``k`` problems at once, one
    compiled ``lax.while_loop``.

    ``parameters [k, 6]`` start each problem (``[phi, translation]`` of
    :func:`_moved_distances`); the residuals and their exact Jacobian come from ``_batched``.
    A problem stops moving once its cost changes by less than ``tolerance`` relatively over
    an accepted step, or once no damping gives a descent step (a local minimum); problems
    with ``stopped [k]`` set never move. From iteration ``prune_after`` on, a problem whose
    cost exceeds four times the least cost (twice the RMS) stops: a start that far behind
    after that many steps sits in another basin. The loop ends after ``iterations`` steps or
    once every problem has stopped. ``iterations``, ``tolerance`` and ``prune_after`` are
    traced, so both phases of :func:`register` share one program. Returns
    ``(parameters [k, 6], cost [k], stopped [k])``.
    """
    constants = (start_rotation, surfaces, points, groups, weights)
    residual, jacobian = _batched(parameters, *constants)
    cost = jnp.sum(residual ** 2, 1)
    k = parameters.shape[0]
    state = (jnp.asarray(0), parameters, residual, jacobian, cost, jnp.full(k, 1e-3),
             jnp.full(k, 2.0), stopped)

    def going(state):
        iteration, *_, stopped = state
        return (iteration < iterations) & ~jnp.all(stopped)

    def step_once(state):
        iteration, parameters, residual, jacobian, cost, damping, growth, stopped = state
        normal = jnp.einsum("kmi,kmj->kij", jacobian, jacobian)
        gradient = jnp.einsum("kmi,km->ki", jacobian, residual)
        scale = damping[:, None] * jnp.maximum(jnp.einsum("kii->ki", normal), 1e-12)
        step = -jnp.linalg.solve(normal + scale[:, :, None] * jnp.eye(6),
                                 gradient[..., None])[..., 0]
        step = jnp.where(stopped[:, None], 0.0, step)
        trial_residual, trial_jacobian = _batched(parameters + step, *constants)
        trial_cost = jnp.sum(trial_residual ** 2, 1)
        predicted = -jnp.einsum("ki,ki->k", step, 2 * gradient + jnp.einsum(
            "kij,kj->ki", normal, step))
        ratio = (cost - trial_cost) / jnp.where(predicted > 0, predicted, jnp.inf)
        accept = (ratio > 0) & ~stopped
        stopped = stopped | (accept & (cost - trial_cost <= tolerance * cost))
        parameters = jnp.where(accept[:, None], parameters + step, parameters)
        residual = jnp.where(accept[:, None], trial_residual, residual)
        jacobian = jnp.where(accept[:, None, None], trial_jacobian, jacobian)
        cost = jnp.where(accept, trial_cost, cost)
        damping = jnp.where(accept, damping * jnp.maximum(1 / 3, 1 - (2 * ratio - 1) ** 3),
                            jnp.minimum(damping * growth, 1e13))
        growth = jnp.where(accept, 2.0, jnp.minimum(growth * 2, 1e3))
        stopped = stopped | (damping >= 1e13)  # no descent step left: a (local) minimum
        stopped = stopped | ((iteration >= prune_after) & (cost > 4 * jnp.min(cost)))
        return (iteration + 1, parameters, residual, jacobian, cost, damping, growth,
                stopped)

    _, parameters, _, _, cost, _, _, stopped = jax.lax.while_loop(going, step_once, state)
    return parameters, cost, stopped


def _principal_axes(points: np.ndarray) -> np.ndarray:
    """Columns: principal axes of ``[m, 3]`` points, largest spread first, right-handed."""
    _, vectors = np.linalg.eigh(np.cov((points - points.mean(0)).T))
    vectors = vectors[:, ::-1].copy()
    if np.linalg.det(vectors) < 0:
        vectors[:, 2] *= -1
    return vectors


def start_rotations(marker_points: np.ndarray, model_points: np.ndarray) -> list[np.ndarray]:
    """Starting rotations: principal axes of the markers onto those of the model, the four
    proper sign choices, each also turned by +-90 degrees about each model axis (28)."""
    model_axes, marker_axes = _principal_axes(model_points), _principal_axes(marker_points)
    turns = [np.eye(3)] + [Rotation.from_rotvec(sign * np.pi / 2 * axis).as_matrix()
                           for axis in model_axes.T for sign in (1, -1)]
    rotations = []
    for flips in ((1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1)):
        aligned = model_axes @ np.diag(flips) @ marker_axes.T
        rotations += [turn @ aligned for turn in turns]
    return rotations


def refuse_degenerate_markers(points: np.ndarray, source: str) -> None:
    """Raise ``ValueError`` (naming ``source``) unless the tube markers ``[m, 3]`` [m]
    determine a rigid motion: at least three distinct points, not all on one line (a
    rotation about that line would leave every distance unchanged)."""
    distinct = np.unique(points, axis=0)
    if len(distinct) < 3:
        raise ValueError(f"{source}: a registration needs at least 3 distinct tube markers, "
                         f"found {len(distinct)} distinct position"
                         f"{'s' if len(distinct) != 1 else ''} among {len(points)} markers")
    spread = np.linalg.svd(distinct - distinct.mean(0), compute_uv=False)
    if spread[1] <= 1e-9 * spread[0]:
        raise ValueError(f"{source}: the tube markers all lie on one line: a rotation about "
                         "it is not determined, so no registration is (measure markers "
                         "off that line)")


def register(surfaces: TubeSurfaces, markers: MarkerSet, *, spanwise_groups="auto",
             canopy_group: str = CANOPY_GROUP, max_iterations: int = 60,
             start: Registration | None = None) -> RegistrationResult:
    """Best rigid registration of ``markers`` onto ``surfaces`` (search in the module
    docstring). ``spanwise_groups``: ``"auto"`` (the largest numbered family among the
    marker groups, see :func:`fitting._shape.markers.spanwise_family`), a tuple of group
    names in spanwise order, or ``()`` to keep the numbering as it is.

    ``start``: a registration of the same markers onto a nearby shape (e.g. the last
    evaluation of a fit): no search, only the tight phase from it, with its group matching
    (its spanwise order and groups; ``spanwise_groups`` and ``canopy_group`` are then
    ignored). It finds the minimum of the basin ``start`` lies in, which is the search's
    winner while the shape moves little."""
    if start is not None:
        spanwise_groups, canopy_group = start.spanwise_groups, start.canopy_group
        orders = (start.reversed_order,)
    else:
        if spanwise_groups == "auto":
            spanwise_groups = spanwise_family(g for g in markers.group_names
                                              if g != canopy_group)
        spanwise_groups = tuple(spanwise_groups)
        orders = (False, True) if spanwise_groups else (False,)
    groups = np.stack([marker_surface_groups(
        markers, surfaces, spanwise_groups=spanwise_groups, reversed_order=order,
        canopy_group=canopy_group) for order in orders])
    tube = np.flatnonzero(groups[0] >= 0)
    if tube.size < 3:
        raise ValueError(f"{markers.source}: a registration needs at least 3 tube markers, "
                         f"found {tube.size}")
    measured = np.asarray(markers.position)[tube]
    refuse_degenerate_markers(measured, markers.source)
    centroid = measured.mean(0)
    # Padded to a multiple of 48 markers (weight 0) so marker files of similar size (e.g.
    # the V3 cases, 62-65 tube markers) share one compiled program.
    padded = -(-tube.size // 48) * 48
    points = np.zeros((padded, 3))
    points[:tube.size] = measured - centroid
    weights = np.zeros(padded)
    weights[:tube.size] = 1.0
    padded_groups = np.zeros((len(orders), padded), int)
    padded_groups[:, :tube.size] = groups[:, tube]
    used = np.isin(np.asarray(surfaces.segment_group), groups[0, tube])
    model_points = np.asarray(surfaces.node_positions)[
        np.asarray(surfaces.segment_nodes)[used].reshape(-1)]
    if start is None:
        rotations = start_rotations(measured, model_points)
        initial = np.tile(np.concatenate([np.zeros(3), model_points.mean(0)]),
                          (len(rotations) * len(orders), 1))
    else:
        rotations = [np.asarray(rotation_matrix(start.rotation_vector))]
        initial = np.concatenate([np.zeros(3), np.asarray(start.translation) + (
            centroid - np.asarray(start.marker_centroid)) @ rotations[0].T])[None]
    start_rotation = np.asarray(rotations * len(orders))              # [k, 3, 3]
    order = np.repeat(np.arange(len(orders)), len(rotations))         # [k]
    constants = (jnp.asarray(start_rotation), surfaces, jnp.asarray(points),
                 jnp.asarray(padded_groups[order]), jnp.asarray(weights))
    parameters = jnp.asarray(initial)
    if start is None:
        parameters, cost, _ = _batched_levenberg_marquardt(
            parameters, jnp.zeros(len(start_rotation), bool), jnp.asarray(max_iterations),
            jnp.asarray(1e-8), jnp.asarray(10), *constants)
        rms = np.sqrt(np.asarray(cost) / tube.size)
        rms_by_order = {orders[j]: float(rms[order == j].min()) for j in range(len(orders))}
        best = int(np.argmin(rms))
    else:
        rms_by_order, best = {}, 0
    # The best start is then iterated alone to a tight tolerance (the same compiled loop).
    parameters, cost, converged = _batched_levenberg_marquardt(
        parameters, jnp.asarray(np.arange(len(start_rotation)) != best), jnp.asarray(200),
        jnp.asarray(1e-14), jnp.asarray(200), *constants)
    parameters, cost, converged = np.asarray(parameters), np.asarray(cost), np.asarray(converged)
    rotation = np.asarray(rotation_matrix(jnp.asarray(parameters[best, :3]))) @ \
        start_rotation[best]
    registration = Registration(jnp.asarray(Rotation.from_matrix(rotation).as_rotvec()),
                                jnp.asarray(parameters[best, 3:]), jnp.asarray(centroid),
                                spanwise_groups, orders[order[best]], canopy_group)
    final = float(np.sqrt(cost[best] / tube.size))
    rms_by_order[orders[order[best]]] = final
    message = "converged" if converged[best] else "iteration limit reached"
    return RegistrationResult(registration, final, rms_by_order, len(start_rotation),
                              bool(converged[best]), message)
