"""Readers of the shape files: measured markers, node positions, tubes and canopy triangles.

All four are CSV files with a header row; units are part of the column names (SI inside).
Every problem in a file is collected and reported at once, each naming the file, the line
(the header is line 1) and the column, with what was expected and what was found
(:class:`ShapeFileError`). Nothing here imports the solver.

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
"""

from __future__ import annotations

import csv
import dataclasses
import math
import re
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

import jaxtube as jt

from .._data.errors import TableFileError

_COORDINATE_SPELLINGS = (("x_m", "y_m", "z_m", 1.0),
                         ("x_mm", "y_mm", "z_mm", jt.unit_factor("length", "mm")),
                         ("x", "y", "z", 1.0))


#: One problem in a shape file: ``source:line: column 'name': message`` (the engine's record).
ShapeFileProblem = jt.Problem


class ShapeFileError(TableFileError):
    """An invalid marker, positions, tubes or triangles file (``kind``); ``problems`` lists
    them all."""

    max_listed = 20

    def __init__(self, problems: Sequence[jt.Problem], kind: str):
        self.file_kind = kind
        super().__init__(problems)


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


class _Reader:
    """Rows of one CSV file and the problems found in them."""

    def __init__(self, path, kind: str):
        self.path = Path(path)
        self.source = str(path)
        self.kind = kind
        self.report = jt.ProblemReport(self.source)
        try:
            with open(self.path, newline="", encoding="utf-8-sig") as handle:
                table = list(csv.reader(handle))
        except (OSError, UnicodeDecodeError) as error:
            raise ShapeFileError([ShapeFileProblem(
                self.source, f"cannot read the file: {error}", line=0)], kind) from None
        while table and not any(cell.strip() for cell in table[-1]):
            table.pop()
        if not table:
            self.fail(1, None, "the file is empty; expected a header row and data rows")
        self.header = [cell.strip() for cell in table[0]] if table else []
        self.rows = []
        for number, cells in enumerate(table[1:], start=2):
            if not any(cell.strip() for cell in cells):
                continue
            if len(cells) != len(self.header):
                self.problem(number, None, f"expected {len(self.header)} fields like the "
                                           f"header, found {len(cells)}")
                continue
            self.rows.append((number, dict(zip(self.header, (c.strip() for c in cells)))))
        if table and not self.rows and not len(self.report):
            self.problem(2, None, "no data rows after the header")

    def problem(self, line: int, column: str | None, message: str) -> None:
        self.report.add("", message, line=line, column=column)

    def fail(self, line: int, column: str | None, message: str):
        self.problem(line, column, message)
        self.finish()

    def finish(self) -> None:
        if len(self.report):
            raise ShapeFileError(self.report.problems, self.kind)

    def require(self, *columns: str) -> None:
        missing = [c for c in columns if c not in self.header]
        if missing:
            self.fail(1, None, f"missing column{'s' if len(missing) > 1 else ''} "
                               f"{', '.join(missing)}; the header is {','.join(self.header)!r}")

    def one_of(self, families: Sequence[tuple[str, ...]], what: str) -> tuple[str, ...]:
        present = [f for f in families if any(c in self.header for c in f)]
        if len(present) != 1 or not all(c in self.header for c in present[0]):
            spellings = " or ".join(",".join(f) for f in families)
            self.fail(1, None, f"expected {what} as {spellings} (exactly one spelling, all "
                               f"of its columns); the header is {','.join(self.header)!r}")
        return present[0]

    def number(self, line: int, row: dict, column: str, check: Callable[[float], bool] = None,
               expected: str = "a finite number") -> float:
        text = row[column]
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or (check is not None and not check(value)):
            self.problem(line, column, f"expected {expected}, found {text!r}")
            return math.nan
        return value

    def integer(self, line: int, row: dict, column: str, low: int = 0,
                high: int | None = None) -> int:
        text = row[column]
        try:
            value = int(text)
        except ValueError:
            value = -1
        if value < low or (high is not None and value > high):
            bound = f" at most {high}" if high is not None else ""
            self.problem(line, column, f"expected an integer >= {low}{bound}, found {text!r}")
            return -1
        return value


def _coordinates(reader: _Reader, line: int, row: dict, columns, scale: float) -> list[float]:
    return [reader.number(line, row, c) * scale for c in columns]


def read_marker_table(path) -> MarkerTable:
    """Read a marker file (format in the module docstring); raises :class:`ShapeFileError`."""
    reader = _Reader(path, "marker")
    reader.require("group")
    index_column = "idx" if "idx" in reader.header and "idx_in_group" not in reader.header \
        else "idx_in_group"
    reader.require(index_column)
    spelling = reader.one_of([s[:3] for s in _COORDINATE_SPELLINGS], "marker coordinates")
    scale = next(s[3] for s in _COORDINATE_SPELLINGS if s[:3] == spelling)
    groups, indices, positions, lines, seen = [], [], [], [], {}
    for line, row in reader.rows:
        name = row["group"]
        if not name:
            reader.problem(line, "group", "expected a group name (e.g. LE, strut0, CAN), "
                                          "found an empty field")
        index = reader.integer(line, row, index_column)
        if name and index >= 0:
            if (name, index) in seen:
                reader.problem(line, index_column, f"marker {name}[{index}] appears twice "
                                                   f"(first on line {seen[name, index]})")
            seen.setdefault((name, index), line)
        groups.append(name)
        indices.append(index)
        positions.append(_coordinates(reader, line, row, spelling, scale))
        lines.append(line)
    reader.finish()
    return MarkerTable(tuple(groups), np.asarray(indices, int), np.asarray(positions, float),
                       np.asarray(lines, int), reader.source)


def load_positions(path) -> np.ndarray:
    """Read ``node,x_m,y_m,z_m`` node positions; returns ``[n, 3]`` [m] in node order."""
    reader = _Reader(path, "positions")
    reader.require("node")
    spelling = reader.one_of([("x_m", "y_m", "z_m"), ("x_mm", "y_mm", "z_mm")],
                             "node coordinates")
    scale = 1.0 if spelling[0] == "x_m" else jt.unit_factor("length", "mm")
    by_node: dict[int, tuple[int, list[float]]] = {}
    for line, row in reader.rows:
        node = reader.integer(line, row, "node")
        coordinates = _coordinates(reader, line, row, spelling, scale)
        if node >= 0:
            if node in by_node:
                reader.problem(line, "node", f"node {node} appears twice (first on line "
                                             f"{by_node[node][0]})")
            by_node.setdefault(node, (line, coordinates))
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
    reader = _Reader(path, "tubes")
    reader.require("group", "node_1", "node_2")
    radius_columns = [c for c in reader.header if _RADIUS_COLUMN.match(c)]
    kinds = {_RADIUS_COLUMN.match(c).group(2) or "" for c in radius_columns}
    if not (len(radius_columns) == 1 and kinds == {""}) and \
            not (len(radius_columns) == 2 and kinds == {"_start", "_end"}):
        reader.fail(1, None, "expected the radius as one column radius_m or diameter_m, or two "
                             "columns radius_start_m,radius_end_m (diameter_ and _mm allowed); "
                             f"the header is {','.join(reader.header)!r}")
    high = None if node_count is None else node_count - 1
    segments = []
    for line, row in reader.rows:
        name = row["group"]
        if not name:
            reader.problem(line, "group", "expected a tube group name, found an empty field")
        ends = [reader.integer(line, row, c, 0, high) for c in ("node_1", "node_2")]
        if ends[0] >= 0 and ends[0] == ends[1]:
            reader.problem(line, "node_2", f"expected a node other than node_1, found {ends[1]}")
        radii = []
        for column in sorted(radius_columns, key=lambda c: "_end" in c):
            kind, _, unit = _RADIUS_COLUMN.match(column).groups()
            scale = (0.5 if kind == "diameter" else 1.0) * jt.unit_factor("length", unit)
            radii.append(reader.number(line, row, column, lambda v: v >= 0,
                                       "a radius >= 0") * scale)
        segments.append((name, ends[0], ends[1], radii[0], radii[-1]))
    reader.finish()
    return segments


def load_triangles(path, node_count: int | None = None) -> np.ndarray:
    """Read canopy triangles ``node_1,node_2,node_3``; returns ``[t, 3]`` node numbers."""
    reader = _Reader(path, "triangles")
    reader.require("node_1", "node_2", "node_3")
    high = None if node_count is None else node_count - 1
    triangles = []
    for line, row in reader.rows:
        corners = [reader.integer(line, row, c, 0, high) for c in ("node_1", "node_2", "node_3")]
        if min(corners) >= 0 and len(set(corners)) < 3:
            reader.problem(line, None, f"expected three different nodes, found {corners}")
        triangles.append(corners)
    reader.finish()
    return np.asarray(triangles, int).reshape(-1, 3)
