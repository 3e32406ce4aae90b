"""Scores of a structure's shape against measured markers: RMS overall, per group, canopy.

:func:`score_shape` registers the markers (:func:`fitting.register`) and reports, in mm:

- ``rms_mm``: the RMS over all tube markers (e.g. leading edge and struts) of the surface
  distance (axis distance minus local radius, markers matched by projection): the peers'
  metric (awegroup/Billow ``docs/table_shape.tex``), and the quantity the registration
  minimises;
- ``group_rms_mm``: the same RMS per marker group;
- ``canopy_rms_mm``: the RMS of canopy markers' distances to the nearest canopy triangle,
  under the same registration (the canopy takes no part in the registration); ``None``
  when there are no canopy markers or the model has no canopy triangles.

The null model is the undeformed structure scored the same way (``score_shape`` on its
surfaces).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._data.units import MM_PER_M
from .markers import CANOPY_GROUP, MarkerSet
from .registration import RegistrationResult, marker_distances, register
from .surfaces import TubeSurfaces

MARKER_CSV_COLUMNS = ("group", "idx", "model_group", "distance_mm", "x_model_m", "y_model_m",
                      "z_model_m", "line")


def _rms_mm(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values ** 2)) * MM_PER_M)


@dataclasses.dataclass(frozen=True, eq=False)
class ShapeScore:
    """A shape's comparison with markers (see the module docstring).

    Attributes:
        rms_mm: RMS [mm] over the tube markers.
        group_rms_mm: ``{marker group: RMS [mm]}``, tube groups and the canopy group.
        canopy_rms_mm: RMS [mm] of the canopy markers, or ``None``.
        markers: the markers.
        distance_mm: ``[m]`` each marker's surface distance [mm] (signed for tube markers).
        registered_m: ``[m, 3]`` markers in the model frame [m].
        model_group: ``m`` the model group each marker was compared with (``"canopy"``).
        registration: the registration and its search.
    """

    rms_mm: float
    group_rms_mm: dict
    canopy_rms_mm: float | None
    markers: MarkerSet
    distance_mm: np.ndarray
    registered_m: np.ndarray
    model_group: tuple[str, ...]
    registration: RegistrationResult

    def summary(self) -> dict:
        """JSON-ready summary: RMS values, registration and its search."""
        found = self.registration
        return {
            "rms_mm": self.rms_mm,
            "group_rms_mm": self.group_rms_mm,
            "canopy_rms_mm": self.canopy_rms_mm,
            "markers": {"tube": int(sum(g != "canopy" for g in self.model_group)),
                        "canopy": int(sum(g == "canopy" for g in self.model_group)),
                        "source": self.markers.source},
            "registration": {
                "rotation_vector_rad": np.asarray(found.registration.rotation_vector).tolist(),
                "translation_m": np.asarray(found.registration.translation).tolist(),
                "marker_centroid_m": np.asarray(found.registration.marker_centroid).tolist(),
                "spanwise_groups": list(found.registration.spanwise_groups),
                "spanwise_order_reversed": found.registration.reversed_order,
                "rms_mm_by_spanwise_order": {("reversed" if k else "as numbered"): v * MM_PER_M
                                             for k, v in found.rms_by_order.items()},
                "starts": found.starts, "converged": found.converged,
                "message": found.message,
            },
        }

    def marker_rows(self) -> list[tuple]:
        """One row per marker, columns :data:`MARKER_CSV_COLUMNS`."""
        return [(g, i, mg, d, *x, line) for g, i, mg, d, x, line in
                zip(self.markers.group, self.markers.index, self.model_group,
                    self.distance_mm.tolist(), self.registered_m.tolist(), self.markers.line)]


def score_shape(surfaces: TubeSurfaces, markers: MarkerSet, *, spanwise_groups="auto",
                canopy_group: str = CANOPY_GROUP) -> ShapeScore:
    """Register ``markers`` onto ``surfaces`` and score them (module docstring)."""
    found = register(surfaces, markers, spanwise_groups=spanwise_groups,
                     canopy_group=canopy_group)
    compared = marker_distances(surfaces, markers, found.registration)
    distance = np.asarray(compared.distance)
    groups = np.asarray(compared.surface_group)
    tube = groups >= 0
    group_rms = {}
    for name in markers.group_names:
        members = np.asarray([g == name for g in markers.group])
        if name != canopy_group or surfaces.has_canopy:
            group_rms[name] = _rms_mm(distance[members])
    canopy = ~tube
    canopy_rms = _rms_mm(distance[canopy]) if canopy.any() and surfaces.has_canopy else None
    model_group = tuple("canopy" if g < 0 else surfaces.group_names[g] for g in groups)
    return ShapeScore(_rms_mm(distance[tube]), group_rms, canopy_rms, markers,
                      distance * MM_PER_M, np.asarray(compared.registered), model_group, found)
