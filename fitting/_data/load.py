"""Reading and checking a measurement file (the format: :mod:`fitting._data`)."""

from __future__ import annotations

import csv
import dataclasses
import decimal
import io
import math
import os
from pathlib import Path

import jaxtube as jt

from .curves import MeasuredCurve, MeasuredData
from .errors import DataError
from .setups import _setup_problem
from .units import (
    COLUMN_UNITS,
    OPTIONAL_COLUMNS,
    QUANTITIES,
    SPECIMEN_QUANTITIES,
    accepted_columns,
    to_si,
)


@dataclasses.dataclass
class _Row:
    line: int
    curve: str | None = None
    setup: str | None = None
    values: dict[str, float] = dataclasses.field(default_factory=dict)
    text: dict[str, str] = dataclasses.field(default_factory=dict)
    note: str = ""
    usable: bool = True


def _parse_header(header: list[str], problem) -> list[str | None]:
    """Give each column its role; report header problems.

    Returns one role per column: ``curve``, ``setup``, ``weight``, ``note``, a quantity
    name, or ``None`` for a column to skip (reported as a problem).
    """
    roles: dict[str, str] = {}
    seen: dict[str, int] = {}
    by_quantity: dict[str, list[str]] = {quantity: [] for quantity in QUANTITIES}
    misnamed: set[str] = set()
    for column in header:
        seen[column] = seen.get(column, 0) + 1
        if seen[column] == 2:
            problem(1, column, "expected each column once, found it more than once")
        if seen[column] > 1:
            continue
        quantity, underscore, unit = column.partition("_")
        if column in ("curve", "setup") or column in OPTIONAL_COLUMNS:
            roles[column] = column
        elif underscore and quantity in COLUMN_UNITS:
            if unit in COLUMN_UNITS[quantity]:
                by_quantity[quantity].append(column)
                roles[column] = quantity
            else:
                misnamed.add(quantity)  # reported here, not again as a missing column
                problem(
                    1, column,
                    f"unknown unit {unit!r} for {quantity}; accepted columns: "
                    f"{accepted_columns(quantity)}",
                )
        else:
            expected = ", ".join(
                ["curve", "setup"] + [f"{q}_<unit>" for q in QUANTITIES]
            )
            problem(
                1, column or None,
                f"unknown column {column!r}; expected {expected}, "
                f"optionally {' and '.join(OPTIONAL_COLUMNS)}",
            )
    for name in ("curve", "setup"):
        if name not in roles:
            problem(1, name, f"missing column {name!r}; found columns: {', '.join(header)}")
    for quantity, columns in by_quantity.items():
        if not columns and quantity not in misnamed:
            problem(
                1, quantity,
                f"missing column for {quantity}; expected one of "
                f"{accepted_columns(quantity)}, found columns: {', '.join(header)}",
            )
        elif len(columns) > 1:
            for column in columns[1:]:
                problem(
                    1, column,
                    f"expected exactly one column for {quantity}, found "
                    f"{', '.join(columns)}",
                )
                del roles[column]
    # A repeated column keeps its role on its first occurrence only.
    first_index = {column: header.index(column) for column in roles}
    return [roles[c] if first_index.get(c) == i else None for i, c in enumerate(header)]


def _parse_number(text: str) -> tuple[decimal.Decimal | None, str | None]:
    """Parse a number; return ``(value, None)`` or ``(None, what was wrong)``."""
    if not text:
        return None, "expected a number, found an empty field"
    try:
        value = decimal.Decimal(text)
    except decimal.InvalidOperation:
        return None, f"expected a number, found {text!r}"
    if not value.is_finite():
        return None, f"expected a finite number, found {text!r}"
    return value, None


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
    source = str(path)
    report = jt.ProblemReport(source)

    def problem(line: int, column: str | None, message: str) -> None:
        report.add("", message, line=line, column=column)

    def fail() -> DataError:
        order = {column: i for i, column in enumerate(header)} if header else {}
        return DataError(sorted(report.problems,
                                key=lambda p: (p.line, order.get(p.column, len(order)))))

    header: list[str] = []
    raw = path.read_bytes()
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        line = raw[: error.start].count(b"\n") + 1
        problem(line, None, f"expected UTF-8 text, found byte {raw[error.start]:#04x}")
        raise fail() from None
    if not text.strip():
        problem(1, None, "empty file; expected a header line such as "
                "curve,setup,pressure_bar,radius_m,length_m,deflection_mm,force_N")
        raise fail()

    reader = csv.reader(io.StringIO(text, newline=""))
    header = [cell.strip() for cell in next(reader)]
    roles = _parse_header(header, problem)

    rows: list[_Row] = []
    for cells in reader:
        line = reader.line_num
        if not any(cell.strip() for cell in cells):
            continue  # blank lines carry no data
        row = _Row(line)
        rows.append(row)
        if len(cells) != len(header):
            problem(line, None, f"expected {len(header)} fields as in the header, "
                    f"found {len(cells)}")
            row.usable = False
            # Still count the row in its curve, so that the curve checks stay truthful.
            if "curve" in roles and roles.index("curve") < len(cells):
                row.curve = cells[roles.index("curve")].strip() or None
            continue
        for column, role, cell in zip(header, roles, cells):
            cell = cell.strip()
            if role is None:
                continue
            if role == "curve":
                if cell:
                    row.curve = cell
                else:
                    problem(line, column, "expected a curve name, found an empty field")
                    row.usable = False
            elif role == "setup":
                issue = _setup_problem(cell)
                if issue is None:
                    row.setup = cell
                else:
                    problem(line, column, issue)
                    row.usable = False
            elif role == "note":
                row.note = cell
            else:
                value, issue = _parse_number(cell)
                if issue is None and role == "weight":
                    number = float(value)
                    if number > 0 and math.isfinite(number):
                        row.values[role] = number
                    else:
                        issue = f"expected a positive weight, found {cell!r}"
                elif issue is None:
                    number = to_si(value, role, column.partition("_")[2])
                    if role in SPECIMEN_QUANTITIES and not number > 0:
                        issue = f"expected a positive {role}, found {cell!r}"
                    elif not math.isfinite(number):
                        issue = f"expected a finite {role}, found {cell!r} (overflows)"
                    else:
                        row.values[role] = number
                        row.text[role] = cell
                if issue is not None:
                    problem(line, column, issue)
                    row.usable = False
    if not rows:
        problem(2, None, "expected at least one data row after the header, found none")

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

    if len(report):
        raise fail()

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
