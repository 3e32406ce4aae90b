"""JSON documents of the workbench: non-finite numbers become ``null``.

JSON has no NaN or infinity, and every document the workbench writes (parameters files,
diagnoses, summaries) is written with ``allow_nan=False``, so a non-finite number must be
turned into ``null`` where the document is built. This is the one place that does it.
"""

from __future__ import annotations

import json
import math
from pathlib import Path


def finite_or_none(value) -> float | None:
    """``float(value)``, or None when it is NaN or infinite."""
    value = float(value)
    return value if math.isfinite(value) else None


def finite_row(row: dict) -> dict:
    """``row`` with every non-finite float replaced by None and tuples made lists."""
    return {key: (finite_or_none(value) if isinstance(value, float)
                  else list(value) if isinstance(value, tuple) else value)
            for key, value in row.items()}


def write_json(path: Path, document) -> None:
    """Write ``document`` as indented JSON with a final newline; NaN or infinity is an error
    (turn them into None with :func:`finite_or_none` first)."""
    Path(path).write_text(json.dumps(document, indent=2, allow_nan=False) + "\n")
