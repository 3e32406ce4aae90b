"""The campaign file (TOML): one kite model, how to hang it, and its measured cases.

A campaign names the structure (a kite_fem ``initial.npz``), its suspension and gravity,
the model's parameter values (``[model]``, see :class:`KiteModel`), the hang schedule
(``[hang]``), named line sets (``[line_sets]``: chains of nodes whose neighbours are joined
by lines, e.g. the trailing edge), which model tube each marker group lies on (``[tubes]``),
the measured lengths (``[lengths]``) and the cases (``[[cases]]``: name, pressure, loads,
marker file, lengths row, role). Every key is documented in ``docs/spec-format.md``
("Campaign files"); paths are relative to the campaign file.

:func:`read_campaign` checks everything it can without solving: unknown keys, a node or a
line set the model does not have, a marker or lengths file that is missing, a negative
pressure or mass, a calibration case without markers. Every problem is collected and
reported at once (:class:`CampaignError`: file, key and reason); nothing is written by a
command whose campaign does not read.
"""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

import numpy as np

import jaxtube as jt

from .._shape.files import load_measured_lengths
from .._tables import DataError
from .model import (
    CampaignError,
    KiteModel,
    ProblemCollector,
    parse_document,
    read_model_values,
)

ROLES = ("calibrate", "predict")
#: The axes of a suspension point's offsets (the model file's frame).
AXES = "xyz"
ROUTES = ("gravity", "stages", "drive")


@dataclasses.dataclass(frozen=True)
class CaseLoad:
    """A dead load on one node: ``force_N [3]`` (a mass's weight along gravity, or a mass's
    weight or a force along ``direction``); ``mass_along_gravity``: it is a hanging mass."""

    node: int
    force_N: np.ndarray
    mass_along_gravity: bool


@dataclasses.dataclass(frozen=True)
class CampaignCase:
    """One measured case.

    Attributes:
        name: the case's name (unique).
        pressure_bar: tube overpressure [bar].
        loads: the dead loads besides gravity.
        markers: the marker CSV, or ``None`` (loads only: predicted).
        measured_lengths_m: ``{length name: measured length [m]}`` (may be empty).
        role: ``"calibrate"`` (fitted to) or ``"predict"``.
        route: how the case is hung: ``"gravity"`` (no loads, one stage), ``"stages"``
            (gravity and loads stepped by ``[hang] load_stages``) or ``"drive"`` (one hanging
            mass reached by displacement control, :func:`jaxtube.drive_to_dead_load`).
        published_rms_mm: ``{source: RMS [mm]}`` published for the case (reports only).
    """

    name: str
    pressure_bar: float
    loads: tuple
    markers: Path | None
    measured_lengths_m: dict
    role: str
    route: str
    published_rms_mm: dict


@dataclasses.dataclass(frozen=True)
class HangSchedule:
    """How every case is hung (``[hang]``).

    Attributes:
        max_newton_steps: Newton steps per solve.
        load_stages: fractions of gravity and loads, one solve each (route ``"stages"``;
            route ``"gravity"`` takes the full load in the first and no step after).
        first_stage_tension_smoothing: the lines' slack-taut blend (strain) of the first
            stage of route ``"stages"`` (``None``: the model's own width throughout).
        drive_steps, drive_increment_m: the most displacement-controlled solves of route
            ``"drive"`` and their largest step [m].
    """

    max_newton_steps: int = 400
    load_stages: tuple = (0.2, 0.4, 0.6, 0.8, 1.0)
    first_stage_tension_smoothing: float | None = None
    drive_steps: int = 24
    drive_increment_m: float = 0.2


@dataclasses.dataclass(frozen=True)
class Campaign:
    """A read campaign file (module docstring).

    Attributes:
        path: the campaign file.
        kite_fem: the kite_fem model read (:class:`jaxtube.KiteFemModel`).
        suspension: the fixed nodes.
        gravity: ``[3]`` gravitational acceleration [m/s^2].
        model: the model's parameter values (:class:`KiteModel`).
        hang: the hang schedule.
        line_sets: ``{name: ((node_a, node_b), ...)}``: the lines of each set.
        tubes: ``{marker group: ((node_a, node_b, radius [m]), ...)}``: the beams of the
            tube each marker group lies on (:func:`beam_path`).
        canopy_group: the marker group on the canopy.
        length_pairs: ``{length name: (node_a, node_b)}``.
        cases: the cases, in file order.
        tube_classes: ``{class: (marker group, ...)}``: named sets of ``[tubes]`` groups
            whose tubes share a bending factor (``[tube_classes]``).
        diagnose_baseline: the values the diagnosis' baseline fits (``[diagnose]
            baseline``); diagnose_candidates: the candidate effects' names (``[diagnose]
            candidates``; ``None``: every built-in effect).
        points: ``{name: node}``: named nodes (``[points]``) a point mass may hang from.
    """

    path: Path
    kite_fem: jt.KiteFemModel
    suspension: tuple
    gravity: np.ndarray
    model: KiteModel
    hang: HangSchedule
    line_sets: dict
    tubes: dict
    canopy_group: str
    length_pairs: dict
    cases: tuple
    tube_classes: dict = dataclasses.field(default_factory=dict)
    diagnose_baseline: tuple = ("bending_scale",)
    diagnose_candidates: tuple | None = None
    points: dict = dataclasses.field(default_factory=dict)

    def members(self) -> dict:
        """``{kind: member names}`` of the model's per-member values (line sets, tube
        classes, points, suspension axes ``"NODE.AXIS"``)."""
        return value_members(self.suspension, self.line_sets, self.tube_classes, self.points)

    def case(self, name: str) -> CampaignCase:
        for case in self.cases:
            if case.name == name:
                return case
        raise KeyError(f"{self.path}: no case named {name!r} (cases: "
                       f"{', '.join(c.name for c in self.cases)})")


def value_members(suspension, line_sets, tube_classes, points) -> dict:
    """``{kind: member names}`` of the model's per-member values (:meth:`Campaign.members`)."""
    return {"rest_length_factors": tuple(line_sets), "stiffness_factors": tuple(line_sets),
            "bending_class_factors": tuple(tube_classes), "point_masses_kg": tuple(points),
            "suspension_offsets_mm": tuple(f"{node}.{axis}" for node in suspension
                                           for axis in AXES)}


def _line_set(value, where, checker, model) -> tuple:
    """The node pairs of a line set: a chain ``[n0, n1, ...]`` (neighbours joined) or pairs
    ``[[a, b], ...]``; each pair must be joined by a spring of the model."""
    if not isinstance(value, list) or len(value) < 2:
        checker.add(where, "expected a chain of nodes [n0, n1, ...] or pairs [[a, b], ...]")
        return ()
    pairs = [tuple(p) for p in value] if all(isinstance(p, list) for p in value) else \
        list(zip(value[:-1], value[1:]))
    joined = {tuple(sorted(p)) for p in np.asarray(model.spring_nodes).tolist()}
    out = []
    for a, b in pairs:
        a = checker.node(a, where, model.node_count)
        b = checker.node(b, where, model.node_count)
        if a is None or b is None:
            continue
        if tuple(sorted((a, b))) not in joined:
            checker.add(where, f"no line of the model joins nodes {a} and {b}")
            continue
        out.append((a, b))
    return tuple(out)


def _read_lengths(table, base, checker, model):
    """``(pairs {name: (a, b)}, rows {row value: {name: length [m]}}, case column)``."""
    pairs = {}
    for name, pair in table.get("pairs", {}).items():
        where = f"lengths.pairs.{name}"
        if not (isinstance(pair, list) and len(pair) == 2):
            checker.add(where, f"expected two nodes [a, b], found {pair!r}")
            continue
        a, b = (checker.node(n, where, model.node_count) for n in pair)
        if a is not None and b is not None:
            pairs[name] = (a, b)
    rows = {}
    if "file" not in table:
        if pairs:
            checker.add("lengths.file", "missing (the CSV of measured lengths [m])")
        return pairs, rows, None
    path = base / str(table["file"])
    column = str(table.get("case_column", "case"))
    try:
        rows = load_measured_lengths(path, column, list(pairs))
    except DataError as error:
        checker.add("lengths.file", str(error))
    except FileNotFoundError:
        checker.add("lengths.file", f"file not found: {path}")
    return pairs, rows, column


def _read_load(load, where, checker, model, movable, gravity):
    if not isinstance(load, dict):
        checker.add(where, "expected a table {node = ..., mass_kg = ... | force_N = ..., "
                           "direction = [x, y, z]}")
        return None
    checker.unknown_keys(load, ("node", "mass_kg", "force_N", "direction"), where)
    node = checker.node(load.get("node"), f"{where}.node", model.node_count, movable)
    if ("mass_kg" in load) == ("force_N" in load):
        checker.add(where, "expected exactly one of mass_kg [kg] and force_N [N]")
        return None
    key = "mass_kg" if "mass_kg" in load else "force_N"
    size = checker.number(load, key, where, minimum=0.0)
    direction = load.get("direction")
    if direction is None:
        if key == "force_N":
            checker.add(f"{where}.direction", "missing (a force needs a direction [x, y, z])")
            return None
        unit = gravity / np.linalg.norm(gravity)
    else:
        vector = np.asarray(direction, dtype=float) if isinstance(direction, list) and \
            len(direction) == 3 and all(isinstance(v, int | float) for v in direction) else None
        if vector is None or not np.linalg.norm(vector) > 0:
            checker.add(f"{where}.direction", f"expected a non-zero vector [x, y, z], found "
                                              f"{direction!r}")
            return None
        unit = vector / np.linalg.norm(vector)
    if node is None or size is None:
        return None
    magnitude = size * float(np.linalg.norm(gravity)) if key == "mass_kg" else size
    return CaseLoad(node, magnitude * unit, key == "mass_kg" and direction is None)


def read_campaign(path) -> Campaign:
    """Read and check a campaign file (module docstring); raises :class:`CampaignError`
    listing every problem (file, key, reason)."""
    path = Path(path)
    base = path.parent
    checker = ProblemCollector(path)
    data = parse_document(path, tomllib.loads, tomllib.TOMLDecodeError, "TOML")
    checker.unknown_keys(data, ("structure", "model", "hang", "line_sets", "tubes",
                                "lengths", "cases", "diagnose", "tube_classes", "points"), "")
    structure = data.get("structure", {})
    checker.unknown_keys(structure, ("kite_fem", "suspension", "gravity_m_s2"), "structure")
    if "kite_fem" not in structure:
        raise CampaignError([jt.Problem(str(path), "missing (the kite_fem initial.npz of the "
                                                   "kite)", "structure.kite_fem")])
    try:
        model = jt.read_kite_fem(base / str(structure["kite_fem"]))
    except FileNotFoundError:
        raise CampaignError([jt.Problem(str(path), f"file not found: "
                                        f"{base / str(structure['kite_fem'])}",
                                        "structure.kite_fem")]) from None
    except ValueError as error:
        raise CampaignError([jt.Problem(str(path), str(error), "structure.kite_fem")]) from None
    n = model.node_count
    suspension = tuple(checker.node(v, "structure.suspension", n)
                       for v in structure.get("suspension", []))
    if not suspension:
        checker.add("structure.suspension", "missing (the nodes the kite hangs from)")
    gravity = np.asarray(structure.get("gravity_m_s2", [0.0, 0.0, 9.81]), dtype=float)
    if gravity.shape != (3,) or not np.isfinite(gravity).all() or not np.linalg.norm(gravity):
        checker.add("structure.gravity_m_s2", "expected a non-zero vector [x, y, z] [m/s^2]")
        gravity = np.array([0.0, 0.0, 9.81])
    movable = set(range(n)) - set(model.element_free_nodes().tolist()) - set(suspension)

    line_sets = {name: _line_set(value, f"line_sets.{name}", checker, model)
                 for name, value in data.get("line_sets", {}).items()}

    hang_table = data.get("hang", {})
    checker.unknown_keys(hang_table, [f.name for f in dataclasses.fields(HangSchedule)], "hang")
    defaults = HangSchedule()
    stages = tuple(hang_table.get("load_stages", defaults.load_stages))
    if not stages or not all(isinstance(s, int | float) and 0 < s <= 1 for s in stages) or \
            stages[-1] != 1:
        checker.add("hang.load_stages", f"expected fractions in (0, 1] ending at 1, found "
                                        f"{list(stages)}")
    smoothing = checker.number(hang_table, "first_stage_tension_smoothing", "hang",
                               default=float("nan"), positive=True) \
        if "first_stage_tension_smoothing" in hang_table else None
    hang = HangSchedule(
        int(checker.number(hang_table, "max_newton_steps", "hang",
                           default=defaults.max_newton_steps, positive=True) or 1),
        tuple(float(s) for s in stages), smoothing,
        int(checker.number(hang_table, "drive_steps", "hang", default=defaults.drive_steps,
                           positive=True) or 1),
        checker.number(hang_table, "drive_increment_m", "hang",
                       default=defaults.drive_increment_m, positive=True) or 1.0)

    tubes_table = dict(data.get("tubes", {}))
    canopy_group = str(tubes_table.pop("canopy_group", "CAN"))
    tubes = {}
    for group, ends in tubes_table.items():
        where = f"tubes.{group}"
        if not (isinstance(ends, list) and len(ends) == 2):
            checker.add(where, f"expected the tube's two end nodes [a, b], found {ends!r}")
            continue
        a, b = (checker.node(v, where, n) for v in ends)
        if a is not None and b is not None:
            segments = beam_path(model, a, b)
            if not segments:
                checker.add(where, f"no chain of beams joins nodes {a} and {b}")
            tubes[group] = segments
    if not tubes_table:
        checker.add("tubes", "missing (which tube of the model each marker group lies on)")

    tube_classes = {}
    for name, groups in data.get("tube_classes", {}).items():
        if not (isinstance(groups, list) and groups and all(g in tubes_table for g in groups)):
            checker.add(f"tube_classes.{name}", f"expected a list of [tubes] groups (of: "
                                                f"{', '.join(tubes_table)}), found {groups!r}")
            continue
        tube_classes[name] = tuple(groups)
    points = {}
    for name, node in data.get("points", {}).items():
        node = checker.node(node, f"points.{name}", n, movable)
        if node is not None:
            points[name] = node
    model_values = read_model_values(data.get("model", {}), "model", checker, value_members(
        suspension, line_sets, tube_classes, points))

    pairs, length_rows, column = _read_lengths(data.get("lengths", {}), base, checker, model)
    cases, names = [], set()
    for k, case in enumerate(data.get("cases", [])):
        where = f"cases[{k}]"
        checker.unknown_keys(case, ("name", "pressure_bar", "loads", "markers", "lengths_row",
                                    "role", "route", "published_rms_mm"), where)
        name = str(case.get("name", f"case{k}"))
        if name in names:
            checker.add(f"{where}.name", f"case {name!r} named twice")
        names.add(name)
        where = f"cases[{k}] ({name})"
        pressure = checker.number(case, "pressure_bar", where, positive=True)
        loads = tuple(filter(None, (_read_load(load, f"{where}.loads[{j}]", checker, model,
                                               movable, gravity)
                                    for j, load in enumerate(case.get("loads", [])))))
        markers = None
        if "markers" in case:
            markers = base / str(case["markers"])
            if not markers.is_file():
                checker.add(f"{where}.markers", f"marker file not found: {markers}")
        role = case.get("role", "calibrate" if markers else "predict")
        if role not in ROLES:
            checker.add(f"{where}.role", f"expected one of {', '.join(ROLES)}, found {role!r}")
        elif role == "calibrate" and "markers" not in case:
            checker.add(f"{where}.role", "a calibration case needs markers (no 'markers' "
                                         "file given)")
        lengths = {}
        if "lengths_row" in case:
            row = str(case["lengths_row"])
            if row not in length_rows and column is not None:
                checker.add(f"{where}.lengths_row", f"no row with {column!r} = {row} in the "
                                                    "lengths file")
            lengths = length_rows.get(row, {})
        route = case.get("route", _default_route(loads))
        if route not in ROUTES:
            checker.add(f"{where}.route", f"expected one of {', '.join(ROUTES)}, found "
                                          f"{route!r}")
        elif route == "drive" and not (len(loads) == 1 and loads[0].mass_along_gravity):
            checker.add(f"{where}.route", "'drive' needs exactly one load, a mass_kg without "
                                          "a direction (it hangs along gravity)")
        elif route == "gravity" and loads:
            checker.add(f"{where}.route", "'gravity' takes no loads")
        cases.append(CampaignCase(name, pressure or 1.0, loads, markers, lengths, role, route,
                                  dict(case.get("published_rms_mm", {}))))
    if not cases:
        checker.add("cases", "missing (at least one [[cases]] table)")
    diagnose = data.get("diagnose", {})
    checker.unknown_keys(diagnose, ("baseline", "candidates"), "diagnose")
    lists = {}
    for key, default in (("baseline", ["bending_scale"]), ("candidates", None)):
        value = diagnose.get(key, default)
        if value is not None and not (isinstance(value, list) and value and
                                      all(isinstance(v, str) for v in value)):
            checker.add(f"diagnose.{key}", f"expected a non-empty list of names, found "
                                           f"{value!r}")
            value = None
        lists[key] = None if value is None else tuple(value)
    if len(checker.report):
        raise CampaignError(checker.report.problems)
    return Campaign(path, model, suspension, gravity, model_values, hang, line_sets, tubes,
                    canopy_group, pairs, tuple(cases), tube_classes,
                    lists["baseline"] or ("bending_scale",),
                    lists["candidates"], points)



def _default_route(loads) -> str:
    if not loads:
        return "gravity"
    return "drive" if len(loads) == 1 and loads[0].mass_along_gravity else "stages"


def beam_path(model, start: int, end: int) -> tuple:
    """The beams along the shortest chain of beams from node ``start`` to ``end`` (breadth
    first over ``model.beam_nodes``): ``((node_a, node_b, radius [m]), ...)`` in order, the
    radius half the beam's diameter; ``()`` if no chain joins them."""
    neighbours: dict[int, list] = {}
    for row, (a, b) in enumerate(np.asarray(model.beam_nodes).tolist()):
        neighbours.setdefault(a, []).append((b, row))
        neighbours.setdefault(b, []).append((a, row))
    came_from = {start: None}
    frontier = [start]
    while frontier and end not in came_from:
        following = []
        for node in frontier:
            for other, row in neighbours.get(node, []):
                if other not in came_from:
                    came_from[other] = (node, row)
                    following.append(other)
        frontier = following
    if end not in came_from or start == end:
        return ()
    path, node = [], end
    while came_from[node] is not None:
        previous, row = came_from[node]
        path.append((previous, node, float(model.beam_diameter[row]) / 2))
        node = previous
    return tuple(reversed(path))
