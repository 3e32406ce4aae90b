"""Measured curves in SI units: one specimen's curve, a set of curves, and saving them."""

from __future__ import annotations

import csv
import dataclasses
import decimal
import io
import math
import os
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np

from .setups import _setup_problem
from .units import QUANTITIES, SPECIMEN_QUANTITIES, check_units, format_decimal, from_si


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
        for quantity in SPECIMEN_QUANTITIES:
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
        chosen = check_units(units)
        for curve in self.curves:
            specimen = {
                f"{quantity}_{chosen[quantity]}": from_si(
                    getattr(curve, quantity), quantity, chosen[quantity]
                )
                for quantity in SPECIMEN_QUANTITIES
            }
            for i in range(curve.point_count):
                yield {
                    "curve": curve.name,
                    "setup": curve.setup,
                    **specimen,
                    f"deflection_{chosen['deflection']}": from_si(
                        float(curve.deflection[i]), "deflection", chosen["deflection"]
                    ),
                    f"force_{chosen['force']}": from_si(
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
        chosen = check_units(units)
        columns = ["curve", "setup"] + [f"{q}_{chosen[q]}" for q in QUANTITIES]
        if any(np.any(curve.weight != 1.0) for curve in self.curves):
            columns.append("weight")
        if any(any(curve.notes) for curve in self.curves):
            columns.append("note")
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(columns)
        for row in self._cells(chosen):
            writer.writerow(
                format_decimal(value) if isinstance(value, decimal.Decimal)
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
