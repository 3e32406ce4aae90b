"""Reading and checking a measurement file (the format: :mod:`fitting._data`), through the
workbench's one table reader (:mod:`fitting._tables`)."""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path

from .._tables import TableReader, TableRow
from .curves import MeasuredCurve, MeasuredData
from .setups import _setup_problem
from .units import (
    COLUMN_UNITS,
    OPTIONAL_COLUMNS,
    QUANTITIES,
    SPECIMEN_QUANTITIES,
    accepted_columns,
    to_si,
)

_EXAMPLE_HEADER = "curve,setup,pressure_bar,radius_m,length_m,deflection_mm,force_N"


@dataclasses.dataclass
class _Row:
    line: int
    curve: str | None = None
    setup: str | None = None
    values: dict[str, float] = dataclasses.field(default_factory=dict)
    text: dict[str, str] = dataclasses.field(default_factory=dict)
    note: str = ""
    usable: bool = True


def _parse_header(reader: TableReader) -> list[str | None]:
    """Give each column its role; report header problems.

    Returns one role per column: ``curve``, ``setup``, ``weight``, ``note``, a quantity
    name, or ``None`` for a column to skip (reported as a problem, or a repeated column,
    which the reader reports).
    """
    header = reader.header
    roles: dict[str, str] = {}
    by_quantity: dict[str, list[str]] = {quantity: [] for quantity in QUANTITIES}
    misnamed: set[str] = set()
    for column in dict.fromkeys(header):
        quantity, underscore, unit = column.partition("_")
        if column in ("curve", "setup") or column in OPTIONAL_COLUMNS:
            roles[column] = column
        elif underscore and quantity in COLUMN_UNITS:
            if unit in COLUMN_UNITS[quantity]:
                by_quantity[quantity].append(column)
                roles[column] = quantity
            else:
                misnamed.add(quantity)  # reported here, not again as a missing column
                reader.problem(
                    1, column,
                    f"unknown unit {unit!r} for {quantity}; accepted columns: "
                    f"{accepted_columns(quantity)}",
                )
        else:
            expected = ", ".join(
                ["curve", "setup"] + [f"{q}_<unit>" for q in QUANTITIES]
            )
            reader.problem(
                1, column or None,
                f"unknown column {column!r}; expected {expected}, "
                f"optionally {' and '.join(OPTIONAL_COLUMNS)}",
            )
    reader.require("curve", "setup")
    for quantity, columns in by_quantity.items():
        if not columns and quantity not in misnamed:
            reader.problem(
                1, None,
                f"missing column for {quantity}; expected one of "
                f"{accepted_columns(quantity)}, found {','.join(header)}",
            )
        elif len(columns) > 1:
            for column in columns[1:]:
                reader.problem(
                    1, column,
                    f"expected exactly one column for {quantity}, found "
                    f"{', '.join(columns)}",
                )
                del roles[column]
    # A repeated column keeps its role on its first occurrence only.
    first_index = {column: header.index(column) for column in roles}
    return [roles[c] if first_index.get(c) == i else None for i, c in enumerate(header)]


def _read_row(reader: TableReader, table_row: TableRow, header, roles) -> _Row:
    """The curve, setup, values and note of one row; its problems recorded."""
    row = _Row(table_row.line)
    cells = table_row.cells
    if not table_row.complete:
        # Still count the row in its curve, so that the curve checks stay truthful.
        row.curve = cells.get("curve") or None
        row.usable = False
        return row
    for column, role in zip(header, roles):
        if role is None:
            continue
        cell = cells[column]
        usable = True
        if role == "curve":
            row.curve = reader.name(table_row, column, "a curve name") or None
            usable = row.curve is not None
        elif role == "setup":
            issue = _setup_problem(cell)
            if issue is None:
                row.setup = cell
            else:
                reader.problem(row.line, column, issue)
                usable = False
        elif role == "note":
            row.note = cell
        elif role == "weight":
            weight = reader.number(table_row, column, check=lambda w: w > 0,
                                   expected="a positive weight")
            usable = math.isfinite(weight)
            if usable:
                row.values[role] = weight
        else:
            value = reader.decimal(table_row, column)
            usable = value is not None
            if usable:
                number = to_si(value, role, column.partition("_")[2])
                issue = None
                if role in SPECIMEN_QUANTITIES and not number > 0:
                    issue = f"expected a positive {role}, found {cell!r}"
                elif not math.isfinite(number):
                    issue = f"expected a finite {role}, found {cell!r} (overflows)"
                if issue is None:
                    row.values[role] = number
                    row.text[role] = cell
                else:
                    reader.problem(row.line, column, issue)
                    usable = False
        row.usable = row.usable and usable
    return row


def load_measurements(path: str | os.PathLike) -> MeasuredData:
    """Read and validate a measurement file (format in the module docstring).

    Args:
        path: the CSV file.

    Returns:
        :class:`MeasuredData` with every quantity in SI units (Pa, m, N); curves in order
        of first appearance, each sorted by ascending deflection.

    Raises:
        DataError: listing every problem found, each with file, line and column.
        OSError: if the file cannot be read.
    """
    path = Path(path)
    reader = TableReader(path, "measurement", _EXAMPLE_HEADER)
    header = reader.header
    roles = _parse_header(reader)
    rows = [_read_row(reader, row, header, roles) for row in reader.rows]
    problem = reader.problem

    # Group by curve name, in order of first appearance.
    groups: dict[str, list[_Row]] = {}
    for row in rows:
        if row.curve is not None:
            groups.setdefault(row.curve, []).append(row)
    column_of = {role: column for column, role in zip(header, roles) if role is not None}
    for name, members in groups.items():
        first = members[0]
        for role in ("setup", *SPECIMEN_QUANTITIES):
            if role not in column_of:
                continue
            column = column_of[role]

            def value_of(row: _Row, role=role):
                return row.setup if role == "setup" else row.values.get(role)

            reference = next((r for r in members if value_of(r) is not None), None)
            if reference is None:
                continue
            shown = reference.setup if role == "setup" else reference.text[role]
            which = "its first row" if reference is first else "its first row with a valid value"
            for row in members:
                value = value_of(row)
                if value is not None and value != value_of(reference):
                    here = row.setup if role == "setup" else row.text[role]
                    problem(
                        row.line, column,
                        f"rows of curve {name!r} disagree: expected {shown!r} as on line "
                        f"{reference.line} ({which}), found {here!r}",
                    )
        usable = [row for row in members if row.usable]
        if not usable:
            problem(first.line, column_of.get("curve"),
                    f"empty curve {name!r}: none of its {len(members)} rows is usable")
        elif len(usable) < 2:
            problem(first.line, column_of.get("curve"),
                    f"curve {name!r} has 1 usable point (line {usable[0].line}); "
                    "expected at least 2")

    reader.finish()

    curves = []
    for name, members in groups.items():
        first = members[0]
        curves.append(
            MeasuredCurve(
                name=name,
                setup=first.setup,
                pressure=first.values["pressure"],
                radius=first.values["radius"],
                length=first.values["length"],
                deflection=[row.values["deflection"] for row in members],
                force=[row.values["force"] for row in members],
                weight=[row.values.get("weight", 1.0) for row in members],
                row_numbers=[row.line for row in members],
                notes=[row.note for row in members],
            )
        )
    return MeasuredData(tuple(curves), source=path)
