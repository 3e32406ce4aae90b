"""Problems found in a table file, and the one error that lists them all.

Problems are the engine's :class:`jaxtube.Problem` records (file, line, column, message),
gathered by a :class:`jaxtube.ProblemReport` as the spec reader's are; the errors here only
say how many there were and list them, one per line.
"""

from __future__ import annotations

from collections.abc import Sequence

import jaxtube as jt

#: One problem found in a measurement file: ``source:line: column 'name': message``
#: (``line`` 1-based, the header is line 1; ``column`` ``None`` for a problem with no
#: column, such as an empty file or a row with the wrong number of fields).
DataProblem = jt.Problem


class TableFileError(ValueError):
    """Invalid table file; ``problems`` lists every :class:`jaxtube.Problem` found, in file
    order, and the message spells out the first ``max_listed`` of them.

    Subclasses name the kind of file (``file_kind``) and how many problems they list.
    """

    file_kind = "table"
    max_listed = 100

    def __init__(self, problems: Sequence[jt.Problem]):
        self.problems = tuple(problems)
        self.source = self.problems[0].source if self.problems else ""
        count = len(self.problems)
        lines = [f"{count} problem{'s' if count != 1 else ''} in {self.file_kind} file "
                 f"{self.source}:"]
        lines += [f"  {problem}" for problem in self.problems[:self.max_listed]]
        if count > self.max_listed:
            lines.append(f"  ... and {count - self.max_listed} more (see .problems)")
        super().__init__("\n".join(lines))


class DataError(TableFileError):
    """Invalid measurement data; ``problems`` lists every problem found, in file order."""

    file_kind = "measurement"
