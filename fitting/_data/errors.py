"""Problems found in a measurement file, and the one error that lists them all."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

# At most this many problems are spelled out in a DataError message.
MAX_LISTED_PROBLEMS = 100




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
        lines += [f"  {problem}" for problem in self.problems[:MAX_LISTED_PROBLEMS]]
        if count > MAX_LISTED_PROBLEMS:
            lines.append(f"  ... and {count - MAX_LISTED_PROBLEMS} more (see .problems)")
        super().__init__("\n".join(lines))
