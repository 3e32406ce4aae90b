"""Measured markers as a PyTree, and which model tube each marker group is compared with.

Marker groups name the model's tube groups (``LE`` to ``LE``, ``strut3`` to ``strut3``),
except that a **spanwise family** (groups ``PREFIX0 .. PREFIX{k-1}``, e.g. ``strut0`` ..
``strut7``) may be numbered from the other wing tip: where port and starboard are not
recorded, the registration tries both orders, ``strutj -> strutj`` and
``strutj -> strut{k-1-j}``. The canopy group (``CAN`` by default) is compared with the
canopy triangles instead of a tube.
"""

from __future__ import annotations

import re

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array

from .files import read_marker_table
from .surfaces import TubeSurfaces

CANOPY_GROUP = "CAN"
_NUMBERED = re.compile(r"^(.*?)(\d+)$")


class MarkerSet(eqx.Module):
    """Measured 3-D markers.

    Attributes:
        position: ``[n, 3]`` marker positions [m] in the measurement frame.
        group: ``n`` group names (static).
        index: ``n`` indices within the group, as measured (static; not used for matching).
        line: ``n`` lines of the markers in their file (static; 0 when not from a file).
        source: the file, or a description (static).
    """

    position: Array
    group: tuple[str, ...] = eqx.field(static=True)
    index: tuple[int, ...] = eqx.field(static=True)
    line: tuple[int, ...] = eqx.field(static=True)
    source: str = eqx.field(static=True, default="markers")

    @classmethod
    def from_arrays(cls, group, position, index=None, source: str = "markers") -> MarkerSet:
        """Markers from ``n`` group names and ``[n, 3]`` positions [m]."""
        position = np.asarray(position, float)
        group = tuple(str(g) for g in group)
        if position.shape != (len(group), 3) or not np.isfinite(position).all():
            raise ValueError(f"expected finite positions of shape ({len(group)}, 3), got "
                             f"{position.shape}")
        if index is None:
            counts: dict[str, int] = {}
            index = []
            for name in group:
                index.append(counts.get(name, 0))
                counts[name] = index[-1] + 1
        return cls(jnp.asarray(position), group, tuple(int(i) for i in index),
                   (0,) * len(group), source)

    @property
    def group_names(self) -> tuple[str, ...]:
        """The groups in order of first appearance."""
        return tuple(dict.fromkeys(self.group))

    def where(self, name: str) -> str:
        """``file:line`` of the first marker of group ``name``, for messages."""
        line = self.line[self.group.index(name)]
        return f"{self.source}:{line}" if line else self.source


def load_markers(path) -> MarkerSet:
    """Read a marker CSV (format in :mod:`fitting._shape.files`) into a :class:`MarkerSet`.
    Raises :class:`fitting.DataError` naming every problem (file, line, column)."""
    table = read_marker_table(path)
    return MarkerSet(jnp.asarray(table.position), table.group, tuple(int(i) for i in table.index),
                     tuple(int(n) for n in table.line), table.source)


def spanwise_family(names) -> tuple[str, ...]:
    """The largest family of groups ``PREFIX0 .. PREFIX{k-1}`` (k >= 2) among ``names``, in
    index order; ``()`` if there is none."""
    families: dict[str, dict[int, str]] = {}
    for name in names:
        match = _NUMBERED.match(name)
        if match:
            families.setdefault(match.group(1), {})[int(match.group(2))] = name
    best: tuple[str, ...] = ()
    for members in families.values():
        k = len(members)
        if k >= 2 and sorted(members) == list(range(k)) and k > len(best):
            best = tuple(members[i] for i in range(k))
    return best


def marker_surface_groups(markers: MarkerSet, surfaces: TubeSurfaces, *,
                          spanwise_groups: tuple[str, ...] = (), reversed_order: bool = False,
                          canopy_group: str = CANOPY_GROUP) -> np.ndarray:
    """``[n]`` index into ``surfaces.group_names`` of the tube each marker is compared with;
    -1 for canopy markers. ``reversed_order`` maps ``spanwise_groups[j]`` to
    ``spanwise_groups[k-1-j]``. Raises ``ValueError`` for a group the model lacks."""
    renamed = dict(zip(spanwise_groups, reversed(spanwise_groups))) if reversed_order else {}
    result = np.empty(len(markers.group), int)
    for name in markers.group_names:
        target = renamed.get(name, name)
        if name == canopy_group:
            index = -1
        elif target in surfaces.group_names:
            index = surfaces.group_names.index(target)
        else:
            raise ValueError(
                f"marker group {name!r} ({markers.where(name)}) names no tube of the model "
                f"(tube groups: {', '.join(surfaces.group_names)}; canopy group: "
                f"{canopy_group!r})")
        result[[g == name for g in markers.group]] = index
    return result
