"""Measured force-deflection curves: loading, validation and saving.

File format
-----------
A measurement file is a long-format CSV (UTF-8, an optional byte-order mark is ignored),
one row per measured point, with a header line::

    curve,setup,pressure_bar,radius_m,length_m,deflection_mm,force_N
    shear-1,cantilever_tip,0.15,0.075,0.6,1.725,1.7114
    shear-1,cantilever_tip,0.15,0.075,0.6,3.514,3.9632
    ...

Columns (in any order):

- ``curve``: the curve name (non-empty text). All rows with the same name form one curve,
  which needs at least 2 points; rows of one curve need not be adjacent.
- ``setup``: the test setup, ``kind`` or ``kind:arguments``. Known kinds:

  - ``cantilever_tip``: horizontal tube clamped at the root, dead vertical tip load;
    the deflection is the vertical tip displacement from the unloaded shape.

- One column per quantity, its unit given by the suffix; values are converted to SI
  (exactly one column per quantity):

  - pressure (gauge, > 0) [Pa]: ``pressure_bar``, ``pressure_kPa`` or ``pressure_Pa``;
  - radius (> 0) [m]: ``radius_m`` or ``radius_mm``;
  - length (> 0) [m]: ``length_m`` or ``length_mm``;
  - deflection (any finite value) [m]: ``deflection_mm`` or ``deflection_m``;
  - force (any finite value) [N]: ``force_N`` or ``force_kN``.

  Pressure, radius, length and setup describe the specimen and must be the same on every
  row of a curve. Deflection and force may take either sign (a bench test may push both
  ways); repeated deflections within a curve are allowed.
- Optional ``weight``: a positive finite per-point weight for the fit (1 when absent).
- Optional ``note``: free text, kept with the point and otherwise ignored.

Any other column is an error. Unit conversion is exact in decimal before rounding to
float64, so ``0.15`` bar, ``15`` kPa and ``15000`` Pa give the same float64 value.

Errors
------
:func:`load_measurements` checks the whole file in one pass and raises a single
:class:`DataError` (a :class:`ValueError`) listing every problem, one per line, each
naming the file, the line (1-based, header = line 1) and the column, and saying what was
expected and what was found. The structured list is in ``DataError.problems``.

Adding a setup kind
-------------------
Setups are parsed through the registry ``_SETUP_KINDS``: a new kind (e.g.
``spec:path/to/structure.toml:node``) is one entry, a :class:`_SetupKind` with a
description and a function that checks the text after ``kind:``.
"""

from __future__ import annotations

import csv
import dataclasses
import decimal
import io
import math
import os
import tempfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np

# --------------------------------------------------------------------------- units

# Quantity -> unit suffix -> exact decimal factor to SI (value_SI = value * factor).
_UNITS: dict[str, dict[str, decimal.Decimal]] = {
    "pressure": {
        "bar": decimal.Decimal("1E+5"),
        "kPa": decimal.Decimal("1E+3"),
        "Pa": decimal.Decimal("1"),
    },
    "radius": {"m": decimal.Decimal("1"), "mm": decimal.Decimal("1E-3")},
    "length": {"m": decimal.Decimal("1"), "mm": decimal.Decimal("1E-3")},
    "deflection": {"mm": decimal.Decimal("1E-3"), "m": decimal.Decimal("1")},
    "force": {"N": decimal.Decimal("1"), "kN": decimal.Decimal("1E+3")},
}
_QUANTITIES = tuple(_UNITS)
# Specimen quantities: positive, and constant within a curve.
_SPECIMEN_QUANTITIES = ("pressure", "radius", "length")
_OPTIONAL_COLUMNS = ("weight", "note")
# Units written by default: those of the shared measurement files.
_DEFAULT_UNITS = {
    "pressure": "bar",
    "radius": "m",
    "length": "m",
    "deflection": "mm",
    "force": "N",
}
# 28 significant digits: exact for any float64 repr (<= 17 digits) times a power of ten.
_DECIMAL_CONTEXT = decimal.Context(prec=28)
# At most this many problems are spelled out in a DataError message.
_MAX_LISTED_PROBLEMS = 100


def _accepted_columns(quantity: str) -> str:
    return ", ".join(f"{quantity}_{unit}" for unit in _UNITS[quantity])


def _to_si(value: decimal.Decimal, quantity: str, unit: str) -> float:
    return float(_DECIMAL_CONTEXT.multiply(value, _UNITS[quantity][unit]))


def _from_si(value: float, quantity: str, unit: str) -> decimal.Decimal:
    # repr() is the shortest decimal that reads back as `value`; dividing it by a power of
    # ten is exact, so writing and reading back gives the same float64 bit for bit.
    return _DECIMAL_CONTEXT.divide(decimal.Decimal(repr(value)), _UNITS[quantity][unit])


def _format_decimal(value: decimal.Decimal) -> str:
    value = value.normalize(_DECIMAL_CONTEXT)
    if -7 <= value.adjusted() < 16:
        return format(value, "f")
    return str(value)


def _check_units(units: Mapping[str, str] | None) -> dict[str, str]:
    chosen = dict(_DEFAULT_UNITS)
    for quantity, unit in (units or {}).items():
        if quantity not in _UNITS:
            raise ValueError(
                f"unknown quantity {quantity!r} in units; expected one of {', '.join(_UNITS)}"
            )
        if unit not in _UNITS[quantity]:
            raise ValueError(
                f"unknown unit {unit!r} for {quantity}; accepted: {', '.join(_UNITS[quantity])}"
            )
        chosen[quantity] = unit
    return chosen


# -------------------------------------------------------------------------- setups


@dataclasses.dataclass(frozen=True)
class _SetupKind:
    """One entry of the setup registry.

    ``check_arguments(text)`` receives what follows ``kind:`` (``""`` when there is no
    colon) and returns ``None`` if valid, or a sentence saying what is wrong.
    """

    description: str
    check_arguments: Callable[[str], str | None]


def _no_arguments(arguments: str) -> str | None:
    if arguments:
        return f"takes no arguments, found {arguments!r}"
    return None


_SETUP_KINDS: dict[str, _SetupKind] = {
    "cantilever_tip": _SetupKind(
        description=(
            "horizontal tube clamped at the root, dead vertical tip load; deflection is "
            "the vertical tip displacement from the unloaded shape"
        ),
        check_arguments=_no_arguments,
    ),
}


def _setup_problem(setup: str) -> str | None:
    """Return what is wrong with a setup string, or ``None`` if it is valid."""
    known = ", ".join(_SETUP_KINDS)
    if not setup:
        return f"expected a setup (one of: {known}), found an empty field"
    kind, _, arguments = setup.partition(":")
    if kind not in _SETUP_KINDS:
        return f"expected a known setup (one of: {known}), found {setup!r}"
    problem = _SETUP_KINDS[kind].check_arguments(arguments)
    if problem is not None:
        return f"setup {kind!r} {problem}"
    return None


# -------------------------------------------------------------------------- errors


@dataclasses.dataclass(frozen=True)
class DataProblem:
    """One problem found in a measurement file.

    Attributes:
        source: the file.
        line: 1-based line number in the file (the header is line 1).
        column: the column name, or ``None`` for a problem with no column (empty file, a
            row with the wrong number of fields).
        message: what was expected and what was found.
    """

    source: str
    line: int
    column: str | None
    message: str

    def __str__(self) -> str:
        where = f"{self.source}:{self.line}"
        if self.column is not None:
            where += f": column {self.column!r}"
        return f"{where}: {self.message}"


class DataError(ValueError):
    """Invalid measurement data; ``problems`` lists every problem found, in file order."""

    def __init__(self, source: str, problems: Sequence[DataProblem]):
        self.source = source
        self.problems = tuple(problems)
        count = len(self.problems)
        lines = [f"{count} problem{'s' if count != 1 else ''} in measurement file {source}:"]
        lines += [f"  {problem}" for problem in self.problems[:_MAX_LISTED_PROBLEMS]]
        if count > _MAX_LISTED_PROBLEMS:
            lines.append(f"  ... and {count - _MAX_LISTED_PROBLEMS} more (see .problems)")
        super().__init__("\n".join(lines))


# ------------------------------------------------------------------------- results


def _frozen_array(values, dtype, name: str) -> np.ndarray:
    array = np.array(values, dtype=dtype)  # a copy: the caller's array stays theirs
    if array.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional, got shape {array.shape}")
    array.setflags(write=False)
    return array


@dataclasses.dataclass(frozen=True, eq=False)
class MeasuredCurve:
    """One measured force-deflection curve of one specimen, in SI units.

    Points are sorted by ascending deflection (a stable sort: equal deflections keep their
    order in the file); ``row_numbers`` gives each point's line in the source file.
    Arrays are float64 (``row_numbers`` int64), read-only, of shape ``[n]`` with
    ``n >= 2``.

    Attributes:
        name: curve name.
        setup: test setup, e.g. ``"cantilever_tip"`` (see the module docstring).
        pressure: gauge inflation pressure [Pa].
        radius: tube radius [m].
        length: tube length [m].
        deflection: ``[n]`` measured deflection [m].
        force: ``[n]`` measured force [N].
        weight: ``[n]`` per-point fit weight (ones when not given).
        row_numbers: ``[n]`` 1-based line numbers in the source file, or ``None`` for a
            curve that was not read from a file.
        notes: ``n`` free-text notes (empty strings when not given).
    """

    name: str
    setup: str
    pressure: float
    radius: float
    length: float
    deflection: np.ndarray
    force: np.ndarray
    weight: np.ndarray | None = None
    row_numbers: np.ndarray | None = None
    notes: tuple[str, ...] | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError(f"curve name must be non-empty text, got {self.name!r}")
        problem = _setup_problem(self.setup)
        if problem is not None:
            raise ValueError(f"curve {self.name!r}: {problem}")
        for quantity in _SPECIMEN_QUANTITIES:
            value = float(getattr(self, quantity))
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"curve {self.name!r}: {quantity} must be > 0, got {value}")
            object.__setattr__(self, quantity, value)
        deflection = _frozen_array(self.deflection, np.float64, "deflection")
        n = deflection.shape[0]
        force = _frozen_array(self.force, np.float64, "force")
        weight = _frozen_array(np.ones(n) if self.weight is None else self.weight,
                               np.float64, "weight")
        notes = ("",) * n if self.notes is None else tuple(str(note) for note in self.notes)
        rows = None if self.row_numbers is None else _frozen_array(
            self.row_numbers, np.int64, "row_numbers")
        lengths = {"force": force.shape[0], "weight": weight.shape[0], "notes": len(notes)}
        if rows is not None:
            lengths["row_numbers"] = rows.shape[0]
        for field, size in lengths.items():
            if size != n:
                raise ValueError(
                    f"curve {self.name!r}: {field} has {size} entries, deflection has {n}"
                )
        if n < 2:
            raise ValueError(f"curve {self.name!r}: needs at least 2 points, got {n}")
        if not (np.all(np.isfinite(deflection)) and np.all(np.isfinite(force))):
            raise ValueError(f"curve {self.name!r}: deflection and force must be finite")
        if not np.all(np.isfinite(weight) & (weight > 0)):
            raise ValueError(f"curve {self.name!r}: weights must be positive and finite")
        order = np.argsort(deflection, kind="stable")
        object.__setattr__(self, "deflection", _frozen_array(deflection[order], np.float64,
                                                             "deflection"))
        object.__setattr__(self, "force", _frozen_array(force[order], np.float64, "force"))
        object.__setattr__(self, "weight", _frozen_array(weight[order], np.float64, "weight"))
        if rows is not None:
            rows = _frozen_array(rows[order], np.int64, "row_numbers")
        object.__setattr__(self, "row_numbers", rows)
        object.__setattr__(self, "notes", tuple(notes[i] for i in order))

    @property
    def point_count(self) -> int:
        """Number of points ``n``."""
        return int(self.deflection.shape[0])

    @property
    def setup_kind(self) -> str:
        """The setup kind, without arguments (``"cantilever_tip"``)."""
        return self.setup.partition(":")[0]


@dataclasses.dataclass(frozen=True, eq=False)
class MeasuredData:
    """A set of measured curves, as read by :func:`load_measurements`.

    Attributes:
        curves: the curves, in order of first appearance in the file; names are unique.
        source: the file read, or ``None`` for data built in memory.
    """

    curves: tuple[MeasuredCurve, ...]
    source: Path | None = None

    def __post_init__(self):
        curves = tuple(self.curves)
        if not curves:
            raise ValueError("MeasuredData needs at least one curve")
        for curve in curves:
            if not isinstance(curve, MeasuredCurve):
                raise TypeError(f"expected MeasuredCurve, got {type(curve).__name__}")
        names = [curve.name for curve in curves]
        duplicates = sorted({name for name in names if names.count(name) > 1})
        if duplicates:
            raise ValueError(f"curve names must be unique; repeated: {', '.join(duplicates)}")
        object.__setattr__(self, "curves", curves)
        if self.source is not None:
            object.__setattr__(self, "source", Path(self.source))

    def __len__(self) -> int:
        return len(self.curves)

    def __iter__(self) -> Iterator[MeasuredCurve]:
        return iter(self.curves)

    def __getitem__(self, name: str) -> MeasuredCurve:
        """The curve called ``name``."""
        for curve in self.curves:
            if curve.name == name:
                return curve
        raise KeyError(name)

    def pressures(self) -> np.ndarray:
        """Sorted unique pressures [Pa], shape ``[k]``."""
        return np.unique([curve.pressure for curve in self.curves])

    def radii(self) -> np.ndarray:
        """Sorted unique radii [m], shape ``[k]``."""
        return np.unique([curve.radius for curve in self.curves])

    def lengths(self) -> np.ndarray:
        """Sorted unique lengths [m], shape ``[k]``."""
        return np.unique([curve.length for curve in self.curves])

    @property
    def point_count(self) -> int:
        """Total number of points over all curves."""
        return sum(curve.point_count for curve in self.curves)

    def _cells(self, units: Mapping[str, str] | None) -> Iterator[dict[str, object]]:
        """Rows as ``{column: value}``; quantities as exact decimals in ``units``."""
        chosen = _check_units(units)
        for curve in self.curves:
            specimen = {
                f"{quantity}_{chosen[quantity]}": _from_si(
                    getattr(curve, quantity), quantity, chosen[quantity]
                )
                for quantity in _SPECIMEN_QUANTITIES
            }
            for i in range(curve.point_count):
                yield {
                    "curve": curve.name,
                    "setup": curve.setup,
                    **specimen,
                    f"deflection_{chosen['deflection']}": _from_si(
                        float(curve.deflection[i]), "deflection", chosen["deflection"]
                    ),
                    f"force_{chosen['force']}": _from_si(
                        float(curve.force[i]), "force", chosen["force"]
                    ),
                    "weight": float(curve.weight[i]),
                    "note": curve.notes[i],
                }

    def to_rows(self, units: Mapping[str, str] | None = None) -> list[dict[str, object]]:
        """One dict per point, curve by curve, points by ascending deflection.

        Keys are the column names of the file format for the chosen ``units`` (a mapping
        such as ``{"pressure": "kPa"}``; unnamed quantities use ``pressure_bar``,
        ``radius_m``, ``length_m``, ``deflection_mm``, ``force_N``), plus ``weight`` and
        ``note``. Numbers are floats in those units.
        """
        return [
            {
                key: float(value) if isinstance(value, decimal.Decimal) else value
                for key, value in row.items()
            }
            for row in self._cells(units)
        ]

    def write_csv(self, path: str | os.PathLike, units: Mapping[str, str] | None = None) -> Path:
        """Write the data in the file format that :func:`load_measurements` reads.

        Columns: ``curve, setup`` and the five quantities in ``units`` (as in
        :meth:`to_rows`), then ``weight`` if any weight differs from 1 and ``note`` if any
        note is non-empty. Numbers are written so that reading them back gives the same
        float64 values exactly. The file is written to a temporary file in the same
        directory and moved into place with :func:`os.replace`, so ``path`` is never left
        half-written. Returns ``path``.
        """
        path = Path(path)
        chosen = _check_units(units)
        columns = ["curve", "setup"] + [f"{q}_{chosen[q]}" for q in _QUANTITIES]
        if any(np.any(curve.weight != 1.0) for curve in self.curves):
            columns.append("weight")
        if any(any(curve.notes) for curve in self.curves):
            columns.append("note")
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(columns)
        for row in self._cells(chosen):
            writer.writerow(
                _format_decimal(value) if isinstance(value, decimal.Decimal)
                else repr(value) if isinstance(value, float) else value
                for value in (row[column] for column in columns)
            )
        descriptor, temporary = tempfile.mkstemp(
            dir=path.parent, prefix=f".{path.name}.", suffix=".tmp"
        )
        try:
            with os.fdopen(descriptor, "w", encoding="utf-8", newline="") as file:
                file.write(buffer.getvalue())
                file.flush()
                os.fsync(file.fileno())
            os.chmod(temporary, path.stat().st_mode & 0o7777 if path.exists() else 0o644)
            os.replace(temporary, path)
        except BaseException:
            if os.path.exists(temporary):
                os.unlink(temporary)
            raise
        return path


# ------------------------------------------------------------------------- loading


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
    by_quantity: dict[str, list[str]] = {quantity: [] for quantity in _QUANTITIES}
    misnamed: set[str] = set()
    for column in header:
        seen[column] = seen.get(column, 0) + 1
        if seen[column] == 2:
            problem(1, column, "expected each column once, found it more than once")
        if seen[column] > 1:
            continue
        quantity, underscore, unit = column.partition("_")
        if column in ("curve", "setup") or column in _OPTIONAL_COLUMNS:
            roles[column] = column
        elif underscore and quantity in _UNITS:
            if unit in _UNITS[quantity]:
                by_quantity[quantity].append(column)
                roles[column] = quantity
            else:
                misnamed.add(quantity)  # reported here, not again as a missing column
                problem(
                    1, column,
                    f"unknown unit {unit!r} for {quantity}; accepted columns: "
                    f"{_accepted_columns(quantity)}",
                )
        else:
            expected = ", ".join(
                ["curve", "setup"] + [f"{q}_<unit>" for q in _QUANTITIES]
            )
            problem(
                1, column or None,
                f"unknown column {column!r}; expected {expected}, "
                f"optionally {' and '.join(_OPTIONAL_COLUMNS)}",
            )
    for name in ("curve", "setup"):
        if name not in roles:
            problem(1, name, f"missing column {name!r}; found columns: {', '.join(header)}")
    for quantity, columns in by_quantity.items():
        if not columns and quantity not in misnamed:
            problem(
                1, quantity,
                f"missing column for {quantity}; expected one of "
                f"{_accepted_columns(quantity)}, found columns: {', '.join(header)}",
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
    problems: list[DataProblem] = []

    def problem(line: int, column: str | None, message: str) -> None:
        problems.append(DataProblem(source, line, column, message))

    def fail() -> DataError:
        order = {column: i for i, column in enumerate(header)} if header else {}
        problems.sort(key=lambda p: (p.line, order.get(p.column, len(order))))
        return DataError(source, problems)

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
                    number = _to_si(value, role, column.partition("_")[2])
                    if role in _SPECIMEN_QUANTITIES and not number > 0:
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
        for role in ("setup", *_SPECIMEN_QUANTITIES):
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

    if problems:
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
