"""Structure specs in TOML: loading and validation.

A spec file describes one structure and one load path. :func:`load_spec` reads it, checks
every key and value, and returns ``(structure, params, path, metadata)``: a
:class:`~jaxtube.Structure`, its :class:`~jaxtube.StructureParameters`, a
:class:`~jaxtube.DisplacementControl` or :class:`~jaxtube.ForceControl`, and a
:class:`SpecMetadata` with what the CLI needs for reporting. Every problem raises
:class:`SpecError` (a ``ValueError``) naming the file, the key path (e.g.
``cantilever.toml: tube[0].bending_law.curvature_per_m``), what was expected and what was
found; all problems found in one pass are reported together, one per line.

Spec format (version 1)
-----------------------

Units are part of every key name (``_m``, ``_mm``, ``_bar``, ``_N`` ...); inside jaxtube
everything is SI. A node is named ``"tube:index"``: the tube's name and a node index
(``0`` .. ``segments``), negative from the end (``-1`` is the last node), or ``start`` /
``end``. Vectors are lists of three numbers in the world frame.

Top level (anything else is an error, with a suggestion of the closest allowed key):

- ``format_version`` (optional integer, default 1): the spec format version; this jaxtube
  reads version 1. Tables are only ever added, so a version-1 spec stays valid.
- ``name``, ``description`` (optional strings): copied into the outputs.
- ``[[tube]]`` (one or more), ``[[support]]`` (one or more), ``[[connection]]``,
  ``[[load]]`` (optional, several), ``[gravity]`` (optional), ``[path]`` (required).
- ``[kite]`` (optional): a tube kite (leading-edge arc, struts, tip supports), see
  :mod:`jaxtube._kite_spec` for its keys. It adds the tubes ``le``, ``strut_1``, ...,
  their rigid connections and both tip supports, so ``[[tube]]`` and ``[[support]]`` are
  then optional (further tubes, supports and connections may still be added); node names
  ``le:centre``, ``le:left_tip``, ``le:right_tip``, ``strut_k:root``, ``strut_k:end`` work
  wherever a node is named.
- ``[[point]]``, ``[[line]]``, ``[[pulley]]``, ``[[canopy]]``, ``[[point_mass]]``
  (optional): point nodes (free or fixed), tension-only lines, ropes over pulleys, canopy
  nets of lines and lumped masses; keys in :mod:`jaxtube._spec_elements`. With a fixed
  ``[[point]]`` the ``[[support]]`` tables are optional (a frame held by lines).

``[[tube]]``: one inflated tube, cut into equal rigid segments.

- ``name`` (string, required, unique, no ``:``): used in node names.
- ``segments`` (positive integer, required): number of rigid segments.
- ``pressure_bar`` | ``pressure_kPa`` | ``pressure_Pa`` (exactly one, positive):
  envelope overpressure.
- ``radius_m`` (required): a positive number, or a taper ``[[fraction, radius_m], ...]``
  with fractions of the tube length in ``[0, 1]``, strictly increasing (linear in between,
  constant beyond the first and last pair).
- ``mass_per_length_kg_per_m`` (optional, >= 0, default 0): self-weight.
- ``line_load_N_per_m`` (optional vector, default ``[0, 0, 0]``): uniform dead load per
  unit length, world frame.
- ``[tube.centreline]`` (required), by ``kind``:

  - ``"straight"``: ``start_m``, ``end_m`` (vectors, distinct).
  - ``"arc"``: ``centre + R (cos phi u + sin phi v)`` for ``phi`` from ``start_deg`` to
    ``end_deg``: ``centre_m`` (vector), ``arc_radius_m`` (positive), ``start_deg``,
    ``end_deg`` (numbers, different), ``normal`` (vector, default ``[0, 0, 1]``: the arc
    plane's normal), ``reference`` (vector, default ``[1, 0, 0]``, not parallel to
    ``normal``: ``u`` is ``reference`` made orthogonal to ``normal``, ``v = normal x u``).
  - ``"polyline"``: ``points_m`` (two or more vectors, consecutive ones distinct); the
    nodes are spaced equally along the polyline.

- ``[tube.bending_law]`` (required): the moment-curvature law of bending, by ``kind``:

  - ``"spline"``: the three-regime spline of Breukels & Ockels (2008), either from pivots:

    - ``curvature_per_m``, ``moment_Nm`` (required): ``sum(pivots_per_regime)`` (9)
      positive, strictly increasing values each: the pivots at the reference state;
    - ``reference_pressure_bar`` | ``reference_pressure_kPa`` | ``reference_pressure_Pa``
      (exactly one) and ``reference_radius_m``: the pressure and radius at which the pivots
      hold;
    - ``curvature_exponent``, ``moment_exponent`` (number or list of 9, default 1): pivot
      increments scale as ``(p r^3)^exponent``;
    - ``curvature_radius_exponent``, ``moment_radius_exponent`` (optional, both or
      neither; number or list of 9): the separate form, increments scale as
      ``p^exponent r^radius_exponent``;
    - ``residual_stiffness_ratio`` (positive, default 0.01): collapsed-regime slope as a
      fraction of the initial stiffness;
    - ``pivots_per_regime`` (three positive integers, default ``[3, 3, 3]``);

    or sampled from the tension-field law: ``from_tension_field_wall_modulus_N_per_m``
    (``E t``, positive), with optional ``residual_stiffness_ratio`` and
    ``pivots_per_regime``. The spline is sampled at the tube's pressure and largest radius
    and scales exactly to every other radius.
  - ``"tension_field"``: no-compression membrane tube: ``wall_modulus_N_per_m`` (``E t``,
    positive, required), ``residual_stiffness_ratio`` (>= 0, default 0).
  - ``"empirical_2011"``: Breukels' (2011) cantilever fit; no other keys (valid for about
    r = 0.05-0.15 m, 0.1-1 bar).
  - ``"linear"``: ``stiffness_Nm2`` (EI, positive, required).

- ``[tube.torsion_law]`` (optional): the law of torsion (rate of twist [rad/m] to torque),
  same kinds and keys; ``"empirical_2011"`` gives Breukels' torsion fit here. **Default:
  the bending law itself**, which is only a rough stand-in (GJ/EI = 1/(1 + nu) for a thin
  isotropic tube): give a torsion law whenever torsion matters.

``[[support]]``: ``node`` (required), ``kind`` = ``"clamped"`` (position and rotation
fixed; default) | ``"pinned"`` (position fixed). At least one support; one per node. The
first support is the root of the kinematic tree.

``[[connection]]``: two nodes of different tubes that are one physical node:
``nodes = ["a:3", "b:start"]`` (they must coincide), ``kind`` = ``"rigid"`` (default) |
``"pinned"`` (a free spherical joint).

``[[load]]``: a dead point load: ``node`` (required), ``force_N`` and/or ``torque_Nm``
(vectors; at least one). Several loads on one node add up.

``[gravity]``: ``acceleration_m_per_s2`` (vector, required in the table). Without the
table gravity is off, unless a tube has mass: then it is ``[0, 0, -9.81]``.

``[path]``: the load path, ``steps`` equal steps from zero (exclusive) to the maximum.

- ``control`` (required): ``"displacement"`` | ``"force"``.
- ``steps`` (positive integer, default 20).
- ``node``, ``direction`` (vector, non-zero; normalised): the controlled node and the
  direction along which its displacement and force are measured.
- ``"displacement"``: ``node`` and ``direction`` required, not a supported node;
  ``max_displacement_mm`` (positive, required): the node is driven along ``direction``;
  the reported force is the actuator's reaction. The ``[[load]]`` loads and line loads act
  at full value throughout, as dead loads.
- ``"force"``: ``max_load_factor`` (positive, default 1): the ``[[load]]`` forces and
  torques and the tubes' line loads are scaled by the load factor; gravity is not scaled.
  ``node`` and ``direction`` default to the first load's node and force direction; the
  reported force is the applied force at that node along ``direction``.

Example (the bundled ``jaxtube/examples/cantilever.toml`` has the full version)::

    [[tube]]
    name = "beam"
    segments = 20
    pressure_bar = 0.2
    radius_m = 0.075
    [tube.centreline]
    kind = "straight"
    start_m = [0, 0, 0]
    end_m = [1, 0, 0]
    [tube.bending_law]
    kind = "tension_field"
    wall_modulus_N_per_m = 150e3

    [[support]]
    node = "beam:start"
    kind = "clamped"

    [path]
    control = "displacement"
    node = "beam:end"
    direction = [0, 0, -1]
    max_displacement_mm = 150
    steps = 30
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import os
import sys
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

from ._kite import KITE_NODE_NAMES
from ._laws import (
    AbstractMomentLaw,
    EmpiricalBendingLaw2011,
    EmpiricalTorsionLaw2011,
    LinearLaw,
    SplineLaw,
    TensionFieldLaw,
)
from ._model import DisplacementControl, ForceControl
from ._spec_elements import ELEMENT_TABLES, read_element_tables
from ._structure import (
    STANDARD_GRAVITY,
    Connection,
    Structure,
    StructureParameters,
    Support,
    arc_tube,
    build_structure,
    polyline_tube,
    straight_tube,
)

FORMAT_VERSION = 1
DEFAULT_STEPS = 20
_PRESSURE_UNITS = {"bar": 1.0e5, "kPa": 1.0e3, "Pa": 1.0}
_MISSING = object()


class SpecError(ValueError):
    """A spec that cannot be loaded. ``problems`` holds one line per problem, each naming
    the file and key path; ``str(error)`` is those lines joined."""

    def __init__(self, problems):
        self.problems = tuple(problems)
        super().__init__("\n".join(self.problems))


@dataclasses.dataclass(frozen=True, eq=False)
class SpecMetadata:
    """What a spec says beyond the structure: the path and names, for reporting.

    Attributes:
        source: the spec file as given. name, description: from the spec.
        control: ``"displacement"`` or ``"force"``.
        control_node: global node index of the path node; control_node_ref: its name.
        control_direction: unit vector ``[3]``.
        path_values: ``[K]`` imposed displacements [m] or load factors.
        supports: ``(node_ref, node_id, kind)`` per support.
        loads: ``(node_ref, node_id, force [3] N, torque [3] N m)`` per ``[[load]]``.
        gravity: ``[3]`` [m/s^2]. raw: the parsed TOML document.
    """

    source: str
    name: str
    description: str
    format_version: int
    control: str
    control_node: int
    control_node_ref: str
    control_direction: np.ndarray
    path_values: np.ndarray
    supports: tuple
    loads: tuple
    gravity: np.ndarray
    raw: dict

    @property
    def steps(self) -> int:
        return int(self.path_values.shape[0])


class LoadedSpec(NamedTuple):
    """``(structure, params, path, metadata)``, as returned by :func:`load_spec`."""

    structure: Structure
    params: StructureParameters
    path: DisplacementControl | ForceControl
    metadata: SpecMetadata


# ------------------------------------------------------------------------------------------
# Checking values: every reader records a problem and returns None for a bad value.
# ------------------------------------------------------------------------------------------


class _Problems:
    def __init__(self, source: str):
        self.source = source
        self.lines: list[str] = []

    def add(self, where: str, message: str) -> None:
        self.lines.append(f"{self.source}: {where}: {message}" if where else
                          f"{self.source}: {message}")

    def raise_if_any(self) -> None:
        if self.lines:
            raise SpecError(self.lines)


def _join(where: str, key) -> str:
    if isinstance(key, int):
        return f"{where}[{key}]"
    return f"{where}.{key}" if where else str(key)


def _found(value) -> str:
    if isinstance(value, bool):
        text = f"{str(value).lower()} (a boolean)"
    elif isinstance(value, str):
        text = f"the string {value!r}"
    elif isinstance(value, dict):
        text = "a table"
    elif isinstance(value, list):
        text = f"a list of {len(value)} item{'s' * (len(value) != 1)} {value!r}"
    else:
        text = repr(value)
    return text if len(text) <= 120 else text[:117] + "..."


def _point(vector) -> str:
    return "[" + ", ".join(f"{float(x):.6g}" for x in np.round(vector, 12) + 0.0) + "]"


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _closest(key: str, allowed) -> str:
    match = difflib.get_close_matches(key, list(allowed), n=1, cutoff=0.6)
    return f"; did you mean {match[0]!r}?" if match else ""


def _check_keys(p: _Problems, table: dict, where: str, allowed, required: dict) -> None:
    """Unknown keys (with the closest allowed one) and missing required keys."""
    for key in table:
        if key not in allowed:
            what = "key" if where else "top-level key or table"
            p.add(_join(where, key), f"unknown {what}{_closest(key, allowed)} "
                  f"(allowed here: {', '.join(allowed)})")
    for key, expected in required.items():
        if key not in table:
            p.add(_join(where, key), f"missing required key (expected {expected})")


def _number(p, table, key, where, *, default=_MISSING, minimum=None, positive=False,
            integer=False):
    if key not in table:
        return None if default is _MISSING else default
    value = table[key]
    what = ("a positive " if positive else "a ") + ("integer" if integer else "number")
    if minimum is not None:
        what += f" >= {minimum:g}"
    ok = (isinstance(value, int) and not isinstance(value, bool)) if integer else (
        _is_number(value) and math.isfinite(value))
    if ok and positive and value <= 0:
        ok = False
    if ok and minimum is not None and value < minimum:
        ok = False
    if not ok:
        p.add(_join(where, key), f"expected {what}, found {_found(value)}")
        return None
    return value


def _string(p, table, key, where, *, default=_MISSING, choices=None):
    if key not in table:
        return None if default is _MISSING else default
    value = table[key]
    if not isinstance(value, str):
        expected = f"one of {', '.join(map(repr, choices))}" if choices else "a string"
        p.add(_join(where, key), f"expected {expected}, found {_found(value)}")
        return None
    if choices is not None and value not in choices:
        p.add(_join(where, key), f"expected one of {', '.join(map(repr, choices))}, found "
              f"{value!r}{_closest(value, choices)}")
        return None
    return value


def _vector(p, value, where, *, length=3, nonzero=False):
    """A list of ``length`` finite numbers (the value itself, not a key)."""
    if not (isinstance(value, list) and len(value) == length
            and all(_is_number(x) and math.isfinite(x) for x in value)):
        p.add(where, f"expected a list of {length} numbers, found {_found(value)}")
        return None
    vector = np.asarray(value, dtype=float)
    if nonzero and not np.any(vector):
        p.add(where, "expected a non-zero vector, found [0, 0, 0]")
        return None
    return vector


def _vector_key(p, table, key, where, *, default=_MISSING, nonzero=False):
    if key not in table:
        return None if default is _MISSING else np.asarray(default, dtype=float)
    return _vector(p, table[key], _join(where, key), nonzero=nonzero)


def _table(p, value, where, *, array=False):
    """A table, or (``array``) an array of tables ``[[where]]``; None if the shape is wrong."""
    if array:
        if isinstance(value, list) and all(isinstance(v, dict) for v in value):
            return value
        p.add(where, f"expected an array of tables [[{where}]], found {_found(value)}")
        return None
    if isinstance(value, dict):
        return value
    p.add(where, f"expected a table [{where}], found {_found(value)}")
    return None


def _pressure(p, table, where, prefix):
    """Exactly one of ``{prefix}_bar`` / ``_kPa`` / ``_Pa``, positive, in Pa."""
    keys = [f"{prefix}_{unit}" for unit in _PRESSURE_UNITS]
    given = [k for k in keys if k in table]
    if not given:
        p.add(_join(where, keys[0]), f"missing required key (expected a positive pressure as "
              f"exactly one of {', '.join(keys)})")
        return None
    if len(given) > 1:
        p.add(_join(where, given[1]), f"pressure given twice ({' and '.join(given)}); expected "
              f"exactly one of {', '.join(keys)}")
        return None
    value = _number(p, table, given[0], where, positive=True)
    return None if value is None else value * _PRESSURE_UNITS[given[0].rpartition("_")[2]]


def _increasing(p, value, where, count, what):
    """A list of ``count`` positive, strictly increasing numbers."""
    if not (isinstance(value, list) and all(_is_number(x) and math.isfinite(x)
                                            for x in value)):
        p.add(where, f"expected a list of {count} {what}, found {_found(value)}")
        return None
    if len(value) != count:
        p.add(where, f"expected {count} values ({what}), found {len(value)}")
        return None
    if value[0] <= 0:
        p.add(where, f"expected positive, strictly increasing values, found first value "
              f"{value[0]!r}")
        return None
    for i in range(1, count):
        if value[i] <= value[i - 1]:
            p.add(where, f"expected positive, strictly increasing values, found "
                  f"{value[i]!r} (index {i}, from 0) after {value[i - 1]!r}")
            return None
    return np.asarray(value, dtype=float)


def _exponent(p, table, key, where, count, default):
    """A number or a list of ``count`` numbers."""
    if key not in table:
        return default
    value = table[key]
    if _is_number(value) and math.isfinite(value):
        return float(value)
    if (isinstance(value, list) and len(value) == count
            and all(_is_number(x) and math.isfinite(x) for x in value)):
        return np.asarray(value, dtype=float)
    p.add(_join(where, key), f"expected a number or a list of {count} numbers, found "
          f"{_found(value)}")
    return None


# ------------------------------------------------------------------------------------------
# Laws
# ------------------------------------------------------------------------------------------

LAW_KINDS = ("spline", "tension_field", "empirical_2011", "linear")
_SPLINE_PIVOT_KEYS = ("curvature_per_m", "moment_Nm", "reference_pressure_bar",
                      "reference_pressure_kPa", "reference_pressure_Pa", "reference_radius_m",
                      "curvature_exponent", "moment_exponent", "curvature_radius_exponent",
                      "moment_radius_exponent")
_SPLINE_COMMON_KEYS = ("residual_stiffness_ratio", "pivots_per_regime")
_SPLINE_TENSION_FIELD_KEY = "from_tension_field_wall_modulus_N_per_m"


def _read_law(p, table, where, role, pressure, radius) -> AbstractMomentLaw | None:
    """A law table; ``role`` is "bending" or "torsion"; ``pressure`` [Pa] and the largest
    ``radius`` [m] of the tube (None if invalid) are used by the tension-field spline."""
    table = _table(p, table, where)
    if table is None:
        return None
    if "kind" not in table:
        p.add(_join(where, "kind"), f"missing required key (expected one of "
              f"{', '.join(map(repr, LAW_KINDS))})")
        return None
    kind = _string(p, table, "kind", where, choices=LAW_KINDS)
    if kind is None:
        return None
    count = len(p.lines)
    if kind == "linear":
        _check_keys(p, table, where, ("kind", "stiffness_Nm2"),
                    {"stiffness_Nm2": "a positive stiffness [N m^2]"})
        stiffness = _number(p, table, "stiffness_Nm2", where, positive=True)
        return None if len(p.lines) > count else LinearLaw(float(stiffness))
    if kind == "tension_field":
        _check_keys(p, table, where, ("kind", "wall_modulus_N_per_m", "residual_stiffness_ratio"),
                    {"wall_modulus_N_per_m": "a positive wall modulus E t [N/m]"})
        modulus = _number(p, table, "wall_modulus_N_per_m", where, positive=True)
        ratio = _number(p, table, "residual_stiffness_ratio", where, default=0.0, minimum=0.0)
        return None if len(p.lines) > count else TensionFieldLaw(float(modulus), float(ratio))
    if kind == "empirical_2011":
        _check_keys(p, table, where, ("kind",), {})
        if len(p.lines) > count:
            return None
        return EmpiricalBendingLaw2011() if role == "bending" else EmpiricalTorsionLaw2011()
    return _read_spline(p, table, where, pressure, radius)


def _read_spline(p, table, where, pressure, radius):
    count = len(p.lines)
    from_tension_field = _SPLINE_TENSION_FIELD_KEY in table
    if from_tension_field:
        allowed = ("kind", _SPLINE_TENSION_FIELD_KEY) + _SPLINE_COMMON_KEYS
        for key in table:
            if key in _SPLINE_PIVOT_KEYS:
                p.add(_join(where, key), f"cannot be combined with {_SPLINE_TENSION_FIELD_KEY} "
                      "(give either the pivots or the tension-field wall modulus)")
        _check_keys(p, {k: v for k, v in table.items() if k not in _SPLINE_PIVOT_KEYS}, where,
                    allowed, {})
    else:
        allowed = ("kind",) + _SPLINE_PIVOT_KEYS + _SPLINE_COMMON_KEYS
        _check_keys(p, table, where, allowed + (_SPLINE_TENSION_FIELD_KEY,), {
            "curvature_per_m": f"9 increasing pivot curvatures [1/m] (or give "
                               f"{_SPLINE_TENSION_FIELD_KEY})",
            "moment_Nm": "9 increasing pivot moments [N m]",
            "reference_radius_m": "the positive radius [m] at which the pivots hold",
        })
    ratio = _number(p, table, "residual_stiffness_ratio", where, default=0.01, positive=True)
    pivots_per_regime = (3, 3, 3)
    if "pivots_per_regime" in table:
        value = table["pivots_per_regime"]
        if (isinstance(value, list) and len(value) == 3
                and all(isinstance(n, int) and not isinstance(n, bool) and n > 0
                        for n in value)):
            pivots_per_regime = tuple(value)
        else:
            p.add(_join(where, "pivots_per_regime"), f"expected a list of three positive "
                  f"integers, found {_found(value)}")
            return None
    pivot_count = sum(pivots_per_regime)
    try:
        if from_tension_field:
            modulus = _number(p, table, _SPLINE_TENSION_FIELD_KEY, where, positive=True)
            if len(p.lines) > count or pressure is None or radius is None:
                return None
            return SplineLaw.from_tension_field(
                float(modulus), pressure, radius, residual_stiffness_ratio=float(ratio),
                pivots_per_regime=pivots_per_regime)
        what = f"sum of pivots_per_regime = {list(pivots_per_regime)}"
        curvatures = moments = None
        if "curvature_per_m" in table:
            curvatures = _increasing(p, table["curvature_per_m"],
                                     _join(where, "curvature_per_m"), pivot_count, what)
        if "moment_Nm" in table:
            moments = _increasing(p, table["moment_Nm"], _join(where, "moment_Nm"),
                                  pivot_count, what)
        reference_pressure = _pressure(p, table, where, "reference_pressure")
        reference_radius = _number(p, table, "reference_radius_m", where, positive=True)
        curvature_exponent = _exponent(p, table, "curvature_exponent", where, pivot_count, 1.0)
        moment_exponent = _exponent(p, table, "moment_exponent", where, pivot_count, 1.0)
        radius_keys = ("curvature_radius_exponent", "moment_radius_exponent")
        radius_exponents = None
        if any(k in table for k in radius_keys):
            if not all(k in table for k in radius_keys):
                missing = next(k for k in radius_keys if k not in table)
                p.add(_join(where, missing), "missing key: curvature_radius_exponent and "
                      "moment_radius_exponent go together (give both or neither)")
            else:
                radius_exponents = tuple(_exponent(p, table, k, where, pivot_count, None)
                                         for k in radius_keys)
        if len(p.lines) > count:
            return None
        return SplineLaw.from_pivots(
            curvatures, moments, reference_pressure, float(reference_radius),
            curvature_exponent=curvature_exponent, moment_exponent=moment_exponent,
            radius_exponents=radius_exponents, residual_stiffness_ratio=float(ratio),
            pivots_per_regime=pivots_per_regime)
    except ValueError as error:
        p.add(where, f"invalid spline law: {error}")
        return None


# ------------------------------------------------------------------------------------------
# Tables. Each reader checks one top-level entry and fills the context; a new table (a
# kite's [[canopy]], [[line]], [[point_mass]]) is one more reader in _TABLE_READERS.
# ------------------------------------------------------------------------------------------


@dataclasses.dataclass
class _Context:
    tubes: list = dataclasses.field(default_factory=list)  # Tube or None per [[tube]]
    tube_nodes: dict = dataclasses.field(default_factory=dict)  # name -> node count or None
    supports: list = dataclasses.field(default_factory=list)  # (where, ref, kind)
    connections: list = dataclasses.field(default_factory=list)  # (where, ref_a, ref_b, kind)
    loads: list = dataclasses.field(default_factory=list)  # (where, ref, force, torque)
    gravity: np.ndarray | None = None
    path: dict | None = None
    tube_names_known: bool = True  # False when a tube name is missing or invalid
    node_aliases: dict = dataclasses.field(default_factory=dict)  # "le:centre" -> "le:12"


CENTRELINE_KINDS = ("straight", "arc", "polyline")
_TUBE_KEYS = ("name", "segments", "pressure_bar", "pressure_kPa", "pressure_Pa", "radius_m",
              "mass_per_length_kg_per_m", "line_load_N_per_m", "centreline", "bending_law",
              "torsion_law")


def _radius(p, table, where):
    """A positive number or ``[[fraction, radius], ...]`` (fractions increasing in [0, 1])."""
    if "radius_m" not in table:
        return None
    value, key_where = table["radius_m"], _join(where, "radius_m")
    if _is_number(value):
        if math.isfinite(value) and value > 0:
            return float(value)
        p.add(key_where, f"expected a positive radius, found {_found(value)}")
        return None
    pairs_ok = isinstance(value, list) and len(value) >= 1 and all(
        isinstance(pair, list) and len(pair) == 2
        and all(_is_number(x) and math.isfinite(x) for x in pair) for pair in value)
    if not pairs_ok:
        p.add(key_where, "expected a positive number or a list of [fraction, radius_m] pairs, "
              f"found {_found(value)}")
        return None
    table_array = np.asarray(value, dtype=float)
    fractions, radii = table_array[:, 0], table_array[:, 1]
    if np.any(fractions < 0) or np.any(fractions > 1) or np.any(np.diff(fractions) <= 0):
        p.add(key_where, "expected fractions of the length in [0, 1], strictly increasing, "
              f"found {fractions.tolist()}")
        return None
    if np.any(radii <= 0):
        p.add(key_where, f"expected positive radii, found {radii.tolist()}")
        return None
    return [tuple(pair) for pair in table_array.tolist()]


def _read_centreline(p, table, where):
    """Returns ``(builder, kwargs)`` with ``builder(name, segments, radius, pressure, law,
    **kwargs)`` making the tube, or None."""
    table = _table(p, table, where)
    if table is None:
        return None
    if "kind" not in table:
        p.add(_join(where, "kind"), "missing required key (expected one of "
              f"{', '.join(map(repr, CENTRELINE_KINDS))})")
        return None
    kind = _string(p, table, "kind", where, choices=CENTRELINE_KINDS)
    count = len(p.lines)
    if kind == "straight":
        _check_keys(p, table, where, ("kind", "start_m", "end_m"),
                    {"start_m": "a list of 3 numbers [m]", "end_m": "a list of 3 numbers [m]"})
        start = _vector_key(p, table, "start_m", where)
        end = _vector_key(p, table, "end_m", where)
        if start is not None and end is not None and np.array_equal(start, end):
            p.add(_join(where, "end_m"), f"expected an end different from start_m, found "
                  f"{end.tolist()} for both")
        if len(p.lines) > count:
            return None
        return (lambda name, segments, radius, pressure, law, **kw: straight_tube(
            name, start, end, segments, radius, pressure, law, **kw))
    if kind == "arc":
        _check_keys(p, table, where, ("kind", "centre_m", "arc_radius_m", "start_deg",
                                      "end_deg", "normal", "reference"), {
            "centre_m": "a list of 3 numbers [m]", "arc_radius_m": "a positive radius [m]",
            "start_deg": "a number [degrees]", "end_deg": "a number [degrees]"})
        centre = _vector_key(p, table, "centre_m", where)
        arc_radius = _number(p, table, "arc_radius_m", where, positive=True)
        start = _number(p, table, "start_deg", where)
        end = _number(p, table, "end_deg", where)
        normal = _vector_key(p, table, "normal", where, default=(0, 0, 1), nonzero=True)
        reference = _vector_key(p, table, "reference", where, default=(1, 0, 0), nonzero=True)
        if start is not None and end is not None and start == end:
            p.add(_join(where, "end_deg"), f"expected an angle different from start_deg, found "
                  f"{end!r} for both")
        if normal is not None and reference is not None and np.linalg.norm(
                np.cross(normal, reference)) <= 1e-9 * np.linalg.norm(normal) * np.linalg.norm(
                reference):
            p.add(_join(where, "reference"), f"expected a vector not parallel to normal "
                  f"{normal.tolist()}, found {reference.tolist()}")
        if len(p.lines) > count:
            return None
        return (lambda name, segments, radius, pressure, law, **kw: arc_tube(
            name, centre, arc_radius, math.radians(start), math.radians(end), segments, radius,
            pressure, law, normal=normal, reference=reference, **kw))
    if kind == "polyline":
        _check_keys(p, table, where, ("kind", "points_m"),
                    {"points_m": "a list of two or more points [[x, y, z], ...] [m]"})
        if "points_m" not in table:
            return None
        value, key_where = table["points_m"], _join(where, "points_m")
        if not isinstance(value, list) or len(value) < 2:
            p.add(key_where, f"expected a list of two or more points [[x, y, z], ...], found "
                  f"{_found(value)}")
            return None
        points = [_vector(p, point, _join(key_where, i)) for i, point in enumerate(value)]
        for i in range(1, len(points)):
            if points[i] is not None and points[i - 1] is not None and np.array_equal(
                    points[i], points[i - 1]):
                p.add(_join(key_where, i), f"expected a point different from the previous one, "
                      f"found {points[i].tolist()} twice")
        if len(p.lines) > count:
            return None
        points = np.stack(points)
        return (lambda name, segments, radius, pressure, law, **kw: polyline_tube(
            name, points, segments, radius, pressure, law, **kw))
    return None


def _read_tubes(p, value, ctx: _Context):
    tables = _table(p, value, "tube", array=True)
    if tables is None:
        ctx.tube_names_known = False
        return
    if not tables:
        p.add("tube", "expected at least one [[tube]]")
    for index, table in enumerate(tables):
        where = _join("tube", index)
        count = len(p.lines)
        _check_keys(p, table, where, _TUBE_KEYS, {
            "name": "a tube name (string)", "segments": "a positive integer",
            "radius_m": "a positive radius [m] or [[fraction, radius_m], ...]",
            "centreline": "a [tube.centreline] table", "bending_law": "a [tube.bending_law] table"})
        name = _string(p, table, "name", where)
        if name is not None:
            if not name.strip() or ":" in name:
                p.add(_join(where, "name"), f"expected a non-empty name without ':', found "
                      f"{name!r}")
                name = None
            elif name in ctx.tube_nodes:
                p.add(_join(where, "name"), f"expected a unique tube name, found {name!r} again")
                name = None
        segments = _number(p, table, "segments", where, positive=True, integer=True)
        pressure = _pressure(p, table, where, "pressure")
        radius = _radius(p, table, where)
        mass = _number(p, table, "mass_per_length_kg_per_m", where, default=0.0, minimum=0.0)
        line_load = _vector_key(p, table, "line_load_N_per_m", where, default=(0, 0, 0))
        builder = (_read_centreline(p, table["centreline"], _join(where, "centreline"))
                   if "centreline" in table else None)
        largest_radius = None if radius is None else (
            radius if isinstance(radius, float) else max(r for _, r in radius))
        bending = (_read_law(p, table["bending_law"], _join(where, "bending_law"), "bending",
                             pressure, largest_radius) if "bending_law" in table else None)
        torsion = (_read_law(p, table["torsion_law"], _join(where, "torsion_law"), "torsion",
                             pressure, largest_radius) if "torsion_law" in table else None)
        if name is not None:
            ctx.tube_nodes[name] = None if segments is None else segments + 1
        else:
            ctx.tube_names_known = False
        tube = None
        if len(p.lines) == count:
            try:
                tube = builder(name, segments, radius, pressure, bending, torsion_law=torsion,
                               mass_per_length=float(mass), line_load=line_load)
            except ValueError as error:
                p.add(_join(where, "centreline"), f"cannot build the tube: {error}")
        ctx.tubes.append(tube)


class _Node(NamedTuple):
    name: str  # tube name
    index: int  # node index along the tube, >= 0
    text: str  # as written in the spec


def _node_ref(p, value, where, ctx: _Context) -> _Node | None:
    """A node name checked against the tubes, or None. Kite node names (``le:centre``)
    stand for the ``tube:index`` in ``ctx.node_aliases``; ``text`` keeps what was written."""
    if isinstance(value, str) and value.strip() in ctx.node_aliases:
        node = _node_ref(p, ctx.node_aliases[value.strip()], where, ctx)
        return None if node is None else node._replace(text=value)
    if not isinstance(value, str):
        p.add(where, f"expected a node name 'tube:index' (e.g. 'beam:end'), found "
              f"{_found(value)}")
        return None
    name, sep, index_text = value.rpartition(":")
    name, index_text = name.strip(), index_text.strip()
    index_text = {"start": "0", "end": "-1"}.get(index_text, index_text)
    try:
        index = int(index_text)
    except ValueError:
        index = None
    if not sep or index is None:
        if not ctx.tube_names_known and index_text in KITE_NODE_NAMES:
            return None  # a kite node of a [kite] whose problems are already reported
        p.add(where, f"expected a node name 'tube:index' (index an integer, negative from the "
              f"end, or 'start'/'end'), found {value!r}")
        return None
    if name not in ctx.tube_nodes:
        if not ctx.tube_names_known:  # it may be the tube whose name is already reported
            return None
        tubes = ", ".join(repr(t) for t in ctx.tube_nodes) or "none"
        p.add(where, f"node {value!r} does not exist: no tube named {name!r}"
              f"{_closest(name, ctx.tube_nodes)} (tubes: {tubes})")
        return None
    count = ctx.tube_nodes[name]
    if count is None:  # the tube's segment count is already reported as a problem
        return None
    if not -count <= index < count:
        p.add(where, f"node {value!r} does not exist: tube {name!r} has nodes 0..{count - 1} "
              f"(or -{count}..-1 from the end, 'start', 'end')")
        return None
    return _Node(name, index % count, value)


def _read_supports(p, value, ctx: _Context):
    tables = _table(p, value, "support", array=True)
    if tables is None:
        return
    seen = {}
    for index, table in enumerate(tables):
        where = _join("support", index)
        _check_keys(p, table, where, ("node", "kind"), {"node": "a node name 'tube:index'"})
        ref = _node_ref(p, table["node"], _join(where, "node"), ctx) if "node" in table else None
        kind = _string(p, table, "kind", where, default="clamped", choices=("clamped", "pinned"))
        if ref is not None and ref[:2] in seen:
            same = "" if ref.text == f"{ref.name}:{ref.index}" else \
                f" (= '{ref.name}:{ref.index}')"
            p.add(_join(where, "node"), f"expected one support per node, found node "
                  f"{ref.text!r}{same} also in {seen[ref[:2]]}")
        elif ref is not None:
            seen[ref[:2]] = where
        ctx.supports.append((where, ref, kind))


def _read_connections(p, value, ctx: _Context):
    tables = _table(p, value, "connection", array=True)
    if tables is None:
        return
    for index, table in enumerate(tables):
        where = _join("connection", index)
        _check_keys(p, table, where, ("nodes", "kind"),
                    {"nodes": "two node names ['tube:index', 'tube:index']"})
        kind = _string(p, table, "kind", where, default="rigid", choices=("rigid", "pinned"))
        refs = (None, None)
        if "nodes" in table:
            nodes = table["nodes"]
            if isinstance(nodes, list) and len(nodes) == 2:
                refs = tuple(_node_ref(p, n, _join(_join(where, "nodes"), i), ctx)
                             for i, n in enumerate(nodes))
            else:
                p.add(_join(where, "nodes"), f"expected two node names ['tube:index', "
                      f"'tube:index'], found {_found(nodes)}")
        ctx.connections.append((where, refs[0], refs[1], kind))


def _read_loads(p, value, ctx: _Context):
    tables = _table(p, value, "load", array=True)
    if tables is None:
        return
    for index, table in enumerate(tables):
        where = _join("load", index)
        _check_keys(p, table, where, ("node", "force_N", "torque_Nm"),
                    {"node": "a node name 'tube:index'"})
        ref = _node_ref(p, table["node"], _join(where, "node"), ctx) if "node" in table else None
        if "force_N" not in table and "torque_Nm" not in table:
            p.add(_join(where, "force_N"), "missing key (expected force_N and/or torque_Nm, "
                  "lists of 3 numbers [N], [N m])")
        force = _vector_key(p, table, "force_N", where, default=(0, 0, 0))
        torque = _vector_key(p, table, "torque_Nm", where, default=(0, 0, 0))
        ctx.loads.append((where, ref, force, torque))


def _read_gravity(p, value, ctx: _Context):
    table = _table(p, value, "gravity")
    if table is None:
        return
    _check_keys(p, table, "gravity", ("acceleration_m_per_s2",),
                {"acceleration_m_per_s2": "a list of 3 numbers [m/s^2]"})
    ctx.gravity = _vector_key(p, table, "acceleration_m_per_s2", "gravity")


_PATH_KEYS = {
    "displacement": ("control", "node", "direction", "steps", "max_displacement_mm"),
    "force": ("control", "node", "direction", "steps", "max_load_factor"),
}


def _read_path(p, value, ctx: _Context):
    table = _table(p, value, "path")
    if table is None:
        return
    if "control" not in table:
        p.add("path.control", "missing required key (expected 'displacement' or 'force')")
        return
    control = _string(p, table, "control", "path", choices=tuple(_PATH_KEYS))
    if control is None:
        return
    count = len(p.lines)
    required = {"max_displacement_mm": "a positive displacement [mm]",
                "node": "a node name 'tube:index'",
                "direction": "a non-zero list of 3 numbers"} if control == "displacement" else {}
    _check_keys(p, table, "path", _PATH_KEYS[control], required)
    steps = _number(p, table, "steps", "path", default=DEFAULT_STEPS, positive=True,
                    integer=True)
    node = _node_ref(p, table["node"], "path.node", ctx) if "node" in table else None
    direction = _vector_key(p, table, "direction", "path", nonzero=True)
    maximum = (_number(p, table, "max_displacement_mm", "path", positive=True)
               if control == "displacement" else
               _number(p, table, "max_load_factor", "path", default=1.0, positive=True))
    if control == "displacement" and node is not None:
        for where, ref, _ in ctx.supports:
            if ref is not None and ref[:2] == node[:2]:
                p.add("path.node", f"expected a node that is free to move, found the supported "
                      f"node {node.text!r} ({where})")
    if control == "force":
        loads_known = all(f is not None and t is not None for _, _, f, t in ctx.loads)
        tubes_known = all(t is not None for t in ctx.tubes)
        has_load = any(np.any(f) or np.any(t) for _, _, f, t in ctx.loads) if loads_known \
            else True
        has_line_load = any(bool(np.any(np.asarray(t.line_load))) for t in ctx.tubes) \
            if tubes_known else True
        if not has_load and not has_line_load:
            p.add("path.control", "force control scales the [[load]] forces and torques and the "
                  "tubes' line_load_N_per_m, but the spec has none (add a [[load]])")
        if "node" not in table or "direction" not in table:
            first = next(((r, f) for _, r, f, _ in ctx.loads if f is not None and np.any(f)),
                         None)
            if first is None:
                missing = "path.node" if "node" not in table else "path.direction"
                p.add(missing, "missing key (expected node and direction; they default to the "
                      "node and force direction of the first [[load]] with a force, but there "
                      "is none)")
            else:
                node = node if "node" in table else first[0]
                direction = direction if "direction" in table else first[1]
    if len(p.lines) > count:
        return
    ctx.path = dict(control=control, steps=steps, node=node, direction=direction,
                    maximum=maximum)


def _read_scalar(key, kind):
    def read(p, value, ctx):
        if kind is int and not (isinstance(value, int) and not isinstance(value, bool)):
            p.add(key, f"expected an integer, found {_found(value)}")
        elif kind is int and not 1 <= value <= FORMAT_VERSION:
            p.add(key, f"expected a format version this jaxtube reads (1..{FORMAT_VERSION}), "
                  f"found {value}; a newer jaxtube may read it")
        elif kind is str and not isinstance(value, str):
            p.add(key, f"expected a string, found {_found(value)}")
    return read


def _read_kite(p, value, ctx):
    from ._kite_spec import read_kite  # the kite module reads with this module's helpers

    read_kite(p, value, ctx)


# Order matters: node names need the tubes (and the kite's); the path checks supports and
# loads.
_TABLE_READERS: dict[str, Callable[[_Problems, Any, _Context], None]] = {
    "format_version": _read_scalar("format_version", int),
    "name": _read_scalar("name", str),
    "description": _read_scalar("description", str),
    "tube": _read_tubes,
    "kite": _read_kite,
    "support": _read_supports,
    "connection": _read_connections,
    "load": _read_loads,
    "gravity": _read_gravity,
    "path": _read_path,
}
_REQUIRED_TABLES = {"tube": "one or more [[tube]] tables (or a [kite])", "support": "one or "
                    "more [[support]] tables (or a [kite])", "path": "a [path] table"}
# Reserved for the full kite of a later format version; named here so that a spec using
# them gets a clear message instead of "unknown key".
RESERVED_TABLES: dict[str, str] = {}  # none today: the element tables arrived


# ------------------------------------------------------------------------------------------
# Entry points
# ------------------------------------------------------------------------------------------


def load_spec(path: str | os.PathLike, *, steps: int | None = None) -> LoadedSpec:
    """Load and check a TOML spec file; see the module docstring for the format.

    Arguments:
        path: the ``.toml`` file.
        steps: if given, overrides ``[path].steps``.

    Returns ``(structure, params, path, metadata)`` (a :class:`LoadedSpec`). Raises
    :class:`SpecError` listing every problem found (file, key path, expected, found).
    """
    source = os.fspath(path)
    try:
        with open(source, "rb") as file:
            data = file.read()
    except OSError as error:
        raise SpecError([f"{source}: cannot read the spec file: {error.strerror}"]) from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise SpecError([f"{source}: not UTF-8 text ({error})"]) from None
    return parse_spec(text, source=source, steps=steps)


def parse_spec(text: str, *, source: str = "<spec>", steps: int | None = None) -> LoadedSpec:
    """Like :func:`load_spec`, from the TOML text; ``source`` names it in messages."""
    try:
        document = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise SpecError([f"{source}: TOML syntax error: {error}"]) from None
    return spec_from_dict(document, source=source, steps=steps)


def spec_from_dict(document: dict, *, source: str = "<spec>",
                   steps: int | None = None) -> LoadedSpec:
    """Like :func:`load_spec`, from an already parsed TOML document (a dict)."""
    p = _Problems(source)
    required = {k: v for k, v in _REQUIRED_TABLES.items()
                if "kite" not in document or k not in ("tube", "support")}
    if "point" in document:  # a fixed point may hold the frame instead (checked below)
        required.pop("support", None)
    for key, what in RESERVED_TABLES.items():
        if key in document:
            p.add(key, f"reserved for {what} in a later spec format version; this jaxtube "
                  f"(format version {FORMAT_VERSION}) cannot simulate it yet")
    _check_keys(p, {k: v for k, v in document.items() if k not in RESERVED_TABLES}, "",
                tuple(_TABLE_READERS) + ELEMENT_TABLES, required)
    ctx = _Context()
    for key, read in _TABLE_READERS.items():
        if key in document:
            read(p, document[key], ctx)
    elements = read_element_tables(p, document, ctx)
    if "point" in document and "support" not in document and "kite" not in document \
            and not elements.fixed and not any(  # a bad 'fixed' value is reported already
                isinstance(t, dict) and t.get("fixed", False) is not False
                for t in (document["point"] if isinstance(document["point"], list) else [])):
        p.add("support", "missing required key (expected one or more [[support]] tables, "
              "or a [[point]] with fixed = true holding the structure by lines)")
    if "support" in document and not ctx.supports and isinstance(document["support"], list):
        p.add("support", "expected at least one [[support]]")
    if steps is not None and not (isinstance(steps, int) and steps > 0):
        p.add("path.steps", f"expected a positive integer step count override, found {steps!r}")
    p.raise_if_any()

    tubes_by_name = {t.name: t for t in ctx.tubes}
    for where, ref_a, ref_b, _ in ctx.connections:
        a = np.asarray(tubes_by_name[ref_a[0]].nodes[ref_a[1]])
        b = np.asarray(tubes_by_name[ref_b[0]].nodes[ref_b[1]])
        gap = float(np.linalg.norm(a - b))
        if gap > 1e-9 * max(1.0, float(np.abs(a).max())):
            p.add(_join(where, "nodes"), f"expected coincident nodes, found them {gap:.4g} m "
                  f"apart (at {_point(a)} and {_point(b)} m)")
    p.raise_if_any()

    def name(ref):
        return f"{ref[0]}:{ref[1]}"

    force: dict[str, np.ndarray] = {}
    torque: dict[str, np.ndarray] = {}
    for _, ref, f, t in ctx.loads:
        force[name(ref)] = force.get(name(ref), 0.0) + f
        torque[name(ref)] = torque.get(name(ref), 0.0) + t
    gravity = ctx.gravity
    if gravity is None:
        has_mass = any(float(t.mass_per_length) > 0 for t in ctx.tubes) or elements.has_mass
        gravity = np.array([0.0, 0.0, -STANDARD_GRAVITY if has_mass else 0.0])
    try:
        structure, params = build_structure(
            ctx.tubes,
            [Support(name(ref), kind) for _, ref, kind in ctx.supports],
            [Connection(name(a), name(b), kind) for _, a, b, kind in ctx.connections],
            node_force=force or None, node_torque=torque or None, gravity=gravity,
            **elements.build_arguments())
    except ValueError as error:
        raise SpecError([f"{source}: cannot assemble the structure: {error}"]) from None

    path_spec = ctx.path
    count = path_spec["steps"] if steps is None else steps
    fractions = np.arange(1, count + 1) / count
    node_id = structure.node_id(name(path_spec["node"]))
    direction = path_spec["direction"] / np.linalg.norm(path_spec["direction"])
    if path_spec["control"] == "displacement":
        values = fractions * path_spec["maximum"] * 1e-3
        path = DisplacementControl(node_id, direction, values)
    else:
        values = fractions * path_spec["maximum"]
        path = ForceControl(values)
    metadata = SpecMetadata(
        source=source,
        name=str(document.get("name", "")),
        description=str(document.get("description", "")),
        format_version=int(document.get("format_version", FORMAT_VERSION)),
        control=path_spec["control"],
        control_node=node_id,
        control_node_ref=path_spec["node"].text,
        control_direction=direction,
        path_values=values,
        supports=tuple((ref.text, structure.node_id(name(ref)), kind)
                       for _, ref, kind in ctx.supports),
        loads=tuple((ref.text, structure.node_id(name(ref)), f, t)
                    for _, ref, f, t in ctx.loads),
        gravity=np.asarray(gravity, dtype=float),
        raw=document,
    )
    return LoadedSpec(structure, params, path, metadata)
