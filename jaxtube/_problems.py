"""Problems found in a user's input file, gathered and reported together.

A reader of a spec or a data file does not stop at the first bad value: it records a
:class:`Problem` (the file, where in it, what was expected and what was found) and goes on,
and then raises one error that lists every problem (:meth:`ProblemReport.raise_if_any`).
Nothing is built or written from an input that has a problem.

Where a problem is: a key path in a structured file (``tube[0].bending_law.moment_Nm`` in
a TOML spec), or a line and a column in a table file (``data.csv:12: column 'force_N'``).
"""

from __future__ import annotations

import dataclasses


@dataclasses.dataclass(frozen=True)
class Problem:
    """One problem in an input file.

    Attributes:
        source: the file as the user named it.
        message: what was expected and what was found.
        key: key path in a structured file (e.g. ``"path.steps"``), or ``""``.
        line: 1-based line in a table file (the header is line 1), or ``None``.
        column: column name in a table file, or ``None``.

    ``str(problem)`` is ``source[:line]: [key: ][column 'name': ]message``.
    """

    source: str
    message: str
    key: str = ""
    line: int | None = None
    column: str | None = None

    def __str__(self) -> str:
        parts = [self.source if self.line is None else f"{self.source}:{self.line}"]
        if self.key:
            parts.append(self.key)
        if self.column is not None:
            parts.append(f"column {self.column!r}")
        return ": ".join(parts + [self.message])


class ProblemReport:
    """Collects the :class:`Problem` s found in one file (``source``), in the order found.

    ``len(report)`` is the number of problems so far: a reader compares it before and after
    checking a part of the file to know whether that part was clean.
    """

    def __init__(self, source: str):
        self.source = source
        self._problems: list[Problem] = []

    def add(self, key: str, message: str, *, line: int | None = None,
            column: str | None = None) -> None:
        """Record a problem at key path ``key`` (``""``: none) or at ``line``/``column``."""
        self._problems.append(Problem(self.source, message, key, line, column))

    @property
    def problems(self) -> tuple[Problem, ...]:
        return tuple(self._problems)

    def __len__(self) -> int:
        return len(self._problems)

    def raise_if_any(self, error_type: type[Exception]) -> None:
        """Raise ``error_type(problems)`` (the tuple of :class:`Problem`) if any were found."""
        if self._problems:
            raise error_type(self.problems)
