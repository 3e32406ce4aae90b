"""JSON documents of the workbench: non-finite numbers become ``null``.

JSON has no NaN or infinity. Every document the workbench writes (parameters files,
diagnoses, summaries, study results) goes through :func:`write_json`, which turns a NaN or
infinite number into ``null`` wherever it sits (in dicts, lists, tuples, numpy scalars or
arrays), so that an undefined number (a cross-validation without a valid fold design, a
standard error of a held coordinate) never costs the user the whole document. This is the
one place that does it.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np


def finite_or_none(value) -> float | None:
    """``float(value)``, or None when it is NaN or infinite."""
    value = float(value)
    return value if math.isfinite(value) else None


def finite_row(row: dict) -> dict:
    """``row`` with every non-finite float replaced by None and tuples made lists."""
    return {key: (finite_or_none(value) if isinstance(value, float)
                  else list(value) if isinstance(value, tuple) else value)
            for key, value in row.items()}


def json_ready(document):
    """``document`` as plain JSON types: dicts (keys made strings), lists (from lists,
    tuples and numpy arrays), ``bool``, ``int``, ``str``, None, and finite floats; every NaN
    or infinity, at any depth and of any numeric type (Python or numpy), becomes None."""
    if isinstance(document, dict):
        return {str(key): json_ready(value) for key, value in document.items()}
    if isinstance(document, (list, tuple)):
        return [json_ready(value) for value in document]
    if isinstance(document, np.ndarray):
        return [json_ready(value) for value in document.tolist()]
    if isinstance(document, np.generic):
        document = document.item()
    if isinstance(document, (bool, int, str)) or document is None:
        return document
    if isinstance(document, float):
        return finite_or_none(document)
    raise TypeError(f"not JSON serialisable: {type(document).__name__} ({document!r})")


def write_json(path: Path, document) -> None:
    """Write ``document`` as indented JSON with a final newline, every non-finite number
    written as ``null`` (:func:`json_ready`)."""
    text = json.dumps(json_ready(document), indent=2, allow_nan=False) + "\n"
    Path(path).write_text(text)
