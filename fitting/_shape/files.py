"""Readers of the shape files: measured markers, node positions, tubes and canopy triangles.

All four are CSV files with a header row; units are part of the column names (SI inside).
They are read through the workbench's one table reader (:mod:`fitting._tables`): every
problem in a file is collected and reported at once in one :class:`fitting.DataError`
(``ShapeFileError`` is the same class), each naming the file, the line (the header is line 1)
and the column, with what was expected and what was found. Coordinates must be finite and at
most 1 km in magnitude. Nothing here imports the solver.

**Markers** (:func:`load_markers`), one row per measured point:
``group,idx_in_group,x_m,y_m,z_m``. ``group`` names the tube the marker sits on (``LE``,
``strut0``, ...) or the canopy (``CAN``); ``idx_in_group`` is a non-negative integer, unique
within its group (``idx`` is accepted too). Coordinates in millimetres by suffix:
``x_mm,y_mm,z_mm``. **Unsuffixed ``x,y,z`` are read as metres**: that is the convention of
the photogrammetry exports this format was made for (pimjhaanen/photogrammetry_thesis,
whose files give ``x,y,z`` in metres in the camera frame); a file must use one of the three
spellings for all three coordinates. Other columns are ignored.

**Positions** (:func:`load_positions`), the format ``jaxtube simulate`` writes:
``node,x_m,y_m,z_m`` (or ``_mm``), one row per node, nodes ``0 .. n-1`` each exactly once,
in any order.

**Tubes** (:func:`load_tubes`), one row per axis segment:
``group,node_1,node_2`` and the segment's radius as ``radius_m`` or ``diameter_m`` (constant),
or tapered as ``radius_start_m,radius_end_m`` / ``diameter_start_m,diameter_end_m`` (at
``node_1`` and ``node_2``); ``_mm`` for millimetres.

**Canopy triangles** (:func:`load_triangles`): ``node_1,node_2,node_3``.

**Measured lengths** (:func:`load_measured_lengths`), one row per load case: a column naming
the case and one column per measured length in metres (positive).
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np

import jaxtube as jt

from .._tables import DataError, DataProblem, TableReader

#: The error of a bad shape file: the workbench's one table-file error.
ShapeFileError = DataError
#: One problem in a shape file: ``source:line: column 'name': message`` (the engine's record).
ShapeFileProblem = DataProblem

# The spellings of marker coordinates, each with its length unit.
_COORDINATE_SPELLINGS = {("x_m", "y_m", "z_m"): "m", ("x_mm", "y_mm", "z_mm"): "mm",
                         ("x", "y", "z"): "m"}


@dataclasses.dataclass(frozen=True, eq=False)
class MarkerTable:
    """Measured markers as read from a file (numpy; :class:`fitting.MarkerSet` is the JAX form).

    Attributes:
        group: ``[n]`` group name of each marker, in file order.
        index: ``[n]`` ``idx_in_group`` of each marker.
        position: ``[n, 3]`` positions [m] in the measurement frame.
        line: ``[n]`` line of each marker in the file.
        source: the file.
    """

    group: tuple[str, ...]
    index: np.ndarray
    position: np.ndarray
    line: np.ndarray
    source: str


def read_marker_table(path) -> MarkerTable:
    """Read a marker file (format in the module docstring); raises :class:`fitting.DataError`
    naming every problem, :class:`OSError` if the file cannot be read."""
    reader = TableReader(path, "marker", "group,idx_in_group,x_m,y_m,z_m")
    index_column = "idx" if "idx" in reader.header and "idx_in_group" not in reader.header \
        else "idx_in_group"
    reader.require("group", index_column)
    spelling = reader.one_of(list(_COORDINATE_SPELLINGS), "marker coordinates")
    reader.finish()
    groups, indices, positions, lines, seen = [], [], [], [], {}
    for row in reader.complete_rows:
        name = reader.name(row, "group", "a group name (e.g. LE, strut0, CAN)")
        index = reader.integer(row, index_column)
        if name and index >= 0:
            if (name, index) in seen:
                reader.problem(row.line, index_column, f"marker {name}[{index}] appears twice "
                                                       f"(first on line {seen[name, index]})")
            seen.setdefault((name, index), row.line)
        groups.append(name)
        indices.append(index)
        positions.append(reader.coordinates(row, spelling, _COORDINATE_SPELLINGS[spelling]))
        lines.append(row.line)
    reader.finish()
    return MarkerTable(tuple(groups), np.asarray(indices, int), np.asarray(positions, float),
                       np.asarray(lines, int), reader.source)


def load_positions(path) -> np.ndarray:
    """Read ``node,x_m,y_m,z_m`` node positions; returns ``[n, 3]`` [m] in node order."""
    reader = TableReader(path, "positions", "node,x_m,y_m,z_m")
    reader.require("node")
    spelling = reader.one_of([("x_m", "y_m", "z_m"), ("x_mm", "y_mm", "z_mm")],
                             "node coordinates")
    reader.finish()
    by_node: dict[int, tuple[int, list[float]]] = {}
    for row in reader.complete_rows:
        node = reader.integer(row, "node")
        coordinates = reader.coordinates(row, spelling, _COORDINATE_SPELLINGS[spelling])
        if node >= 0:
            if node in by_node:
                reader.problem(row.line, "node", f"node {node} appears twice (first on line "
                                                 f"{by_node[node][0]})")
            by_node.setdefault(node, (row.line, coordinates))
    missing = sorted(set(range(len(by_node))) - set(by_node))
    if by_node and missing:
        last = max(by_node)
        reader.problem(by_node[last][0], "node", f"expected nodes 0..{len(by_node) - 1} "
                       f"each once; missing {missing[:10]}{' ...' if len(missing) > 10 else ''}")
    reader.finish()
    return np.asarray([by_node[k][1] for k in range(len(by_node))], float)


_RADIUS_COLUMN = re.compile(r"^(radius|diameter)(_start|_end)?_(m|mm)$")


def load_tubes(path, node_count: int | None = None) -> list[tuple[str, int, int, float, float]]:
    """Read tube axis segments; returns ``(group, node_1, node_2, radius_1 [m], radius_2 [m])``
    per row. ``node_count``, when given, bounds the node numbers."""
    reader = TableReader(path, "tubes", "group,node_1,node_2,radius_m")
    reader.require("group", "node_1", "node_2")
    radius_columns = [c for c in reader.header if _RADIUS_COLUMN.match(c)]
    kinds = {_RADIUS_COLUMN.match(c).group(2) or "" for c in radius_columns}
    if not (len(radius_columns) == 1 and kinds == {""}) and \
            not (len(radius_columns) == 2 and kinds == {"_start", "_end"}):
        reader.problem(1, None, "expected the radius as one column radius_m or diameter_m, or "
                                "two columns radius_start_m,radius_end_m (diameter_ and _mm "
                                f"allowed); found {','.join(reader.header)}")
    reader.finish()
    high = None if node_count is None else node_count - 1
    segments = []
    for row in reader.complete_rows:
        name = reader.name(row, "group", "a tube group name")
        ends = [reader.integer(row, c, 0, high) for c in ("node_1", "node_2")]
        if ends[0] >= 0 and ends[0] == ends[1]:
            reader.problem(row.line, "node_2", f"expected a node other than node_1, found "
                                               f"{ends[1]}")
        radii = []
        for column in sorted(radius_columns, key=lambda c: "_end" in c):
            kind, _, unit = _RADIUS_COLUMN.match(column).groups()
            scale = (0.5 if kind == "diameter" else 1.0) * jt.unit_factor("length", unit)
            radii.append(reader.number(row, column, scale, lambda v: v >= 0, "a radius >= 0"))
        segments.append((name, ends[0], ends[1], radii[0], radii[-1]))
    reader.finish()
    return segments


def load_triangles(path, node_count: int | None = None) -> np.ndarray:
    """Read canopy triangles ``node_1,node_2,node_3``; returns ``[t, 3]`` node numbers."""
    reader = TableReader(path, "triangles", "node_1,node_2,node_3")
    reader.require("node_1", "node_2", "node_3")
    reader.finish()
    high = None if node_count is None else node_count - 1
    triangles = []
    for row in reader.complete_rows:
        corners = [reader.integer(row, c, 0, high) for c in ("node_1", "node_2", "node_3")]
        if min(corners) >= 0 and len(set(corners)) < 3:
            reader.problem(row.line, None, f"expected three different nodes, found {corners}")
        triangles.append(corners)
    reader.finish()
    return np.asarray(triangles, int).reshape(-1, 3)


def load_measured_lengths(path, case_column: str,
                          names: list[str] | tuple[str, ...]) -> dict[str, dict[str, float]]:
    """Read measured lengths: ``{case: {name: length [m]}}`` from the columns ``case_column``
    (the case, unique) and ``names`` (positive lengths in metres)."""
    reader = TableReader(path, "lengths", ",".join([case_column, *names]))
    reader.require(case_column, *names)
    reader.finish()
    rows: dict[str, dict[str, float]] = {}
    for row in reader.complete_rows:
        case = reader.name(row, case_column, "a case name")
        lengths = {name: reader.number(row, name, check=lambda x: x > 0,
                                       expected="a positive length [m]") for name in names}
        if case in rows:
            reader.problem(row.line, case_column, f"case {case!r} appears twice")
        rows.setdefault(case, lengths)
    reader.finish()
    return rows
