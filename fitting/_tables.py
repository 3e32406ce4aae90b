"""Reading a table file, and the one error that lists every problem found in it.

Every CSV file the workbench reads (measured curves, markers, node positions, tubes, canopy
triangles) is read through a :class:`TableReader`: UTF-8 text (a byte-order mark is
ignored), a header line, one row per record, blank lines skipped, units in the column names
(SI inside). The reader records each problem as an engine :class:`jaxtube.Problem` (file,
line, column, what was expected and what was found) and goes on; :meth:`TableReader.finish`
raises one :class:`DataError` listing them all in file order. The messages are the same for
every kind of file::

    markers.csv:1: missing column idx_in_group; expected group,idx_in_group,x_m,y_m,z_m,
        found group,x_m,y_m,z_m
    markers.csv:4: expected 5 fields as in the header, found 4
    markers.csv:7: column 'z_m': expected a finite number, found 'inf'
    markers.csv:9: column 'x_m': expected a coordinate of at most 1000 m in magnitude, found '1e300'

Lines are 1-based and the header is line 1. A file that cannot be opened raises the
:class:`OSError` as it is.
"""

from __future__ import annotations

import csv
import dataclasses
import decimal
import io
import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import jaxtube as jt

#: Largest coordinate magnitude [m] a marker or node file may give: a kite on a bench or
#: hanging from a crane is metres across, and a larger value is a unit or export mistake.
MAX_COORDINATE_M = 1e3

#: One problem found in a table file: ``source:line: column 'name': message`` (``line``
#: 1-based, the header is line 1; ``column`` ``None`` for a problem with no column, such as an
#: empty file, a missing column or a row with the wrong number of fields).
DataProblem = jt.Problem


class DataError(ValueError):
    """An invalid table file (measurements, markers, positions, tubes, triangles).

    Attributes:
        problems: every :class:`jaxtube.Problem` found, in file order.
        kind: the kind of file, as the message names it (``"measurement"``, ``"marker"``).
        source: the file.

    The message spells out the first :attr:`max_listed` problems, one per line.
    """

    max_listed = 100

    def __init__(self, problems: Sequence[jt.Problem], kind: str = "measurement"):
        self.problems = tuple(problems)
        self.kind = kind
        self.source = self.problems[0].source if self.problems else ""
        count = len(self.problems)
        lines = [f"{count} problem{'s' if count != 1 else ''} in {kind} file {self.source}:"]
        lines += [f"  {problem}" for problem in self.problems[:self.max_listed]]
        if count > self.max_listed:
            lines.append(f"  ... and {count - self.max_listed} more (see .problems)")
        super().__init__("\n".join(lines))


@dataclasses.dataclass(frozen=True)
class TableRow:
    """One non-blank data row.

    Attributes:
        line: its first line in the file.
        cells: column name -> stripped text (a repeated column keeps its first cell); for an
            incomplete row, only the columns it reaches.
        complete: whether it has as many fields as the header (if not, the reader has
            recorded the problem).
    """

    line: int
    cells: dict[str, str]
    complete: bool


class TableReader:
    """The header and rows of one table file, and the problems found in them.

    Args:
        path: the CSV file.
        kind: the kind of file, for the error message (``"marker"``, ``"tubes"``, ...).
        example_header: a valid header line, quoted when the file is empty.

    Raises:
        DataError: if the file is not UTF-8 or is empty (nothing else can be checked then).
        OSError: if the file cannot be read.
    """

    def __init__(self, path: str | os.PathLike, kind: str, example_header: str):
        self.source = str(path)
        self.kind = kind
        self.example_header = example_header
        self.report = jt.ProblemReport(self.source)
        self.header: list[str] = []
        self.rows: list[TableRow] = []
        raw = Path(path).read_bytes()
        try:
            text = raw.decode("utf-8-sig")
        except UnicodeDecodeError as error:
            line = raw[: error.start].count(b"\n") + 1
            self.problem(line, None, f"expected UTF-8 text, found byte {raw[error.start]:#04x}")
            self.finish()
        if not text.strip():
            self.problem(1, None, f"the file is empty; expected a header line such as "
                                  f"{example_header}")
            self.finish()
        reader = csv.reader(io.StringIO(text, newline=""))
        self.header = [cell.strip() for cell in next(reader)]
        counts: dict[str, int] = {}
        for column in self.header:
            counts[column] = counts.get(column, 0) + 1
            if counts[column] == 2:
                self.problem(1, column, "expected each column once, found it more than once")
        line = reader.line_num + 1
        for cells in reader:
            if any(cell.strip() for cell in cells):
                values: dict[str, str] = {}
                for column, cell in zip(self.header, cells):
                    values.setdefault(column, cell.strip())
                complete = len(cells) == len(self.header)
                if not complete:
                    self.problem(line, None, f"expected {len(self.header)} fields as in the "
                                             f"header, found {len(cells)}")
                self.rows.append(TableRow(line, values, complete))
            line = reader.line_num + 1
        if not self.rows:
            self.problem(2, None, "expected at least one data row after the header, found none")

    @property
    def complete_rows(self) -> list[TableRow]:
        """The rows with as many fields as the header."""
        return [row for row in self.rows if row.complete]

    def problem(self, line: int, column: str | None, message: str) -> None:
        """Record a problem at ``line`` (header: 1) and ``column`` (``None``: the row)."""
        self.report.add("", message, line=line, column=column)

    def finish(self) -> None:
        """Raise one :class:`DataError` listing every problem so far (by line, then column
        order), if there is any."""
        if len(self.report):
            order = {column: i for i, column in enumerate(self.header)}
            problems = sorted(self.report.problems,
                              key=lambda p: (p.line, order.get(p.column, len(order))))
            raise DataError(problems, self.kind)

    def require(self, *columns: str) -> bool:
        """Whether the header has every one of ``columns``; records the missing ones."""
        missing = [column for column in columns if column not in self.header]
        if missing:
            self.problem(1, None, f"missing column{'s' if len(missing) > 1 else ''} "
                                  f"{', '.join(missing)}; expected {self.example_header}, "
                                  f"found {','.join(self.header)}")
        return not missing

    def one_of(self, spellings: Sequence[tuple[str, ...]], what: str) -> tuple[str, ...] | None:
        """The one spelling of ``what`` whose columns are all in the header, or ``None``
        after recording the problem (none, several, or one in part)."""
        present = [s for s in spellings if any(column in self.header for column in s)]
        if len(present) == 1 and all(column in self.header for column in present[0]):
            return present[0]
        self.problem(1, None, f"expected {what} as {' or '.join(','.join(s) for s in spellings)}"
                              f" (exactly one spelling, all of its columns); found "
                              f"{','.join(self.header)}")
        return None

    def name(self, row: TableRow, column: str, what: str) -> str:
        """The non-empty text of ``column`` (``what`` it names, for the message), or ``""``."""
        text = row.cells[column]
        if not text:
            self.problem(row.line, column, f"expected {what}, found an empty field")
        return text

    def decimal(self, row: TableRow, column: str) -> decimal.Decimal | None:
        """The finite decimal number in ``column``, or ``None`` after recording the problem.
        Exact, for unit conversions that round once (:mod:`fitting._data.units`)."""
        text = row.cells[column]
        try:
            value = decimal.Decimal(text)
        except decimal.InvalidOperation:
            value = None
        if value is not None and value.is_finite():
            return value
        found = repr(text) if text else "an empty field"
        self.problem(row.line, column, f"expected a finite number, found {found}")
        return None

    def number(self, row: TableRow, column: str, scale: float = 1.0,
               check: Callable[[float], bool] | None = None,
               expected: str = "a finite number") -> float:
        """``scale`` times the number in ``column`` when it is finite and passes ``check``
        (``expected`` says what passes); NaN after recording the problem."""
        value = self.decimal(row, column)
        if value is None:
            return math.nan
        number = float(value) * scale
        if not math.isfinite(number):
            self.problem(row.line, column, f"expected a finite number, found "
                                           f"{row.cells[column]!r} (overflows)")
            return math.nan
        if check is not None and not check(number):
            self.problem(row.line, column, f"expected {expected}, found {row.cells[column]!r}")
            return math.nan
        return number

    def coordinates(self, row: TableRow, columns: Sequence[str], unit: str) -> list[float]:
        """The point [m] in ``columns``, given in length ``unit`` (``"m"``, ``"mm"``); a
        coordinate larger than :data:`MAX_COORDINATE_M` is a problem."""
        scale = jt.unit_factor("length", unit)
        expected = f"a coordinate of at most {MAX_COORDINATE_M / scale:g} {unit} in magnitude"
        return [self.number(row, column, scale, lambda x: abs(x) <= MAX_COORDINATE_M, expected)
                for column in columns]

    def integer(self, row: TableRow, column: str, low: int = 0,
                high: int | None = None) -> int:
        """The integer in ``column`` within ``[low, high]``, or -1 after recording the
        problem."""
        text = row.cells[column]
        try:
            value = int(text)
        except ValueError:
            value = low - 1
        if value < low or (high is not None and value > high):
            bound = f" at most {high}" if high is not None else ""
            self.problem(row.line, column, f"expected an integer >= {low}{bound}, found {text!r}")
            return -1
        return value
