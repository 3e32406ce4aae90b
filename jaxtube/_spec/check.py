"""The value checkers every spec reader uses: each records a problem and returns ``None``
for a bad value, so that one pass reports every problem of a spec (:class:`SpecError`).

A problem names the file, the key path (``tube[0].bending_law.moment_Nm``), what was
expected and what was found (:mod:`jaxtube._problems`).
"""

from __future__ import annotations

import difflib
import math

import numpy as np

from .._problems import ProblemReport
from .._units import UNITS, unit_factor

MISSING = object()  # "no default": a missing key is reported by check_keys, not here


class SpecError(ValueError):
    """A spec that cannot be loaded. ``problems`` holds one line per problem, each naming
    the file and key path; ``str(error)`` is those lines joined. Built from
    :class:`~jaxtube.Problem` records (``ProblemReport.raise_if_any(SpecError)``) or
    lines."""

    def __init__(self, problems):
        self.problems = tuple(str(problem) for problem in problems)
        super().__init__("\n".join(self.problems))


def key_path(where: str, key) -> str:
    if isinstance(key, int):
        return f"{where}[{key}]"
    return f"{where}.{key}" if where else str(key)


def describe(value) -> str:
    if isinstance(value, bool):
        text = f"{str(value).lower()} (a boolean)"
    elif isinstance(value, str):
        text = f"the string {value!r}"
    elif isinstance(value, dict):
        text = "a table"
    elif isinstance(value, list):
        text = f"a list of {len(value)} item{'s' * (len(value) != 1)} {value!r}"
    else:
        text = repr(value)
    return text if len(text) <= 120 else text[:117] + "..."


def format_point(vector) -> str:
    return "[" + ", ".join(f"{float(x):.6g}" for x in np.round(vector, 12) + 0.0) + "]"


def is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def suggest(key: str, allowed) -> str:
    match = difflib.get_close_matches(key, list(allowed), n=1, cutoff=0.6)
    return f"; did you mean {match[0]!r}?" if match else ""


def check_keys(p: ProblemReport, table: dict, where: str, allowed, required: dict) -> None:
    """Unknown keys (with the closest allowed one) and missing required keys."""
    for key in table:
        if key not in allowed:
            what = "key" if where else "top-level key or table"
            p.add(key_path(where, key), f"unknown {what}{suggest(key, allowed)} "
                  f"(allowed here: {', '.join(allowed)})")
    for key, expected in required.items():
        if key not in table:
            p.add(key_path(where, key), f"missing required key (expected {expected})")


def read_number(p, table, key, where, *, default=MISSING, minimum=None, positive=False,
                integer=False):
    if key not in table:
        return None if default is MISSING else default
    value = table[key]
    what = ("a positive " if positive else "a ") + ("integer" if integer else "number")
    if minimum is not None:
        what += f" >= {minimum:g}"
    ok = (isinstance(value, int) and not isinstance(value, bool)) if integer else (
        is_number(value) and math.isfinite(value))
    if ok and positive and value <= 0:
        ok = False
    if ok and minimum is not None and value < minimum:
        ok = False
    if not ok:
        p.add(key_path(where, key), f"expected {what}, found {describe(value)}")
        return None
    return value


def read_string(p, table, key, where, *, default=MISSING, choices=None):
    if key not in table:
        return None if default is MISSING else default
    value = table[key]
    if not isinstance(value, str):
        expected = f"one of {', '.join(map(repr, choices))}" if choices else "a string"
        p.add(key_path(where, key), f"expected {expected}, found {describe(value)}")
        return None
    if choices is not None and value not in choices:
        p.add(key_path(where, key), f"expected one of {', '.join(map(repr, choices))}, found "
              f"{value!r}{suggest(value, choices)}")
        return None
    return value


def read_vector(p, value, where, *, length=3, nonzero=False):
    """A list of ``length`` finite numbers (the value itself, not a key)."""
    if not (isinstance(value, list) and len(value) == length
            and all(is_number(x) and math.isfinite(x) for x in value)):
        p.add(where, f"expected a list of {length} numbers, found {describe(value)}")
        return None
    vector = np.asarray(value, dtype=float)
    if nonzero and not np.any(vector):
        p.add(where, "expected a non-zero vector, found [0, 0, 0]")
        return None
    return vector


def read_vector_key(p, table, key, where, *, default=MISSING, nonzero=False):
    if key not in table:
        return None if default is MISSING else np.asarray(default, dtype=float)
    return read_vector(p, table[key], key_path(where, key), nonzero=nonzero)


def read_table(p, value, where, *, array=False):
    """A table, or (``array``) an array of tables ``[[where]]``; None if the shape is wrong."""
    if array:
        if isinstance(value, list) and all(isinstance(v, dict) for v in value):
            return value
        p.add(where, f"expected an array of tables [[{where}]], found {describe(value)}")
        return None
    if isinstance(value, dict):
        return value
    p.add(where, f"expected a table [{where}], found {describe(value)}")
    return None


def array_tables(p, value, where) -> list[tuple[str, dict]]:
    """``(key path, table)`` for each table of the array of tables ``[[where]]``; none (and
    a problem) if ``value`` is not one."""
    tables = read_table(p, value, where, array=True)
    return [(key_path(where, index), table) for index, table in enumerate(tables or [])]


def read_pressure(p, table, where, prefix):
    """Exactly one of ``{prefix}_bar`` / ``_kPa`` / ``_Pa``, positive, in Pa."""
    keys = [f"{prefix}_{unit}" for unit in UNITS["pressure"]]
    given = [k for k in keys if k in table]
    if not given:
        p.add(key_path(where, keys[0]), f"missing required key (expected a positive pressure as "
              f"exactly one of {', '.join(keys)})")
        return None
    if len(given) > 1:
        p.add(key_path(where, given[1]), f"pressure given twice ({' and '.join(given)}); expected "
              f"exactly one of {', '.join(keys)}")
        return None
    value = read_number(p, table, given[0], where, positive=True)
    return None if value is None else value * unit_factor("pressure", given[0].rpartition("_")[2])


def read_increasing(p, value, where, count, what):
    """A list of ``count`` positive, strictly increasing numbers."""
    if not (isinstance(value, list) and all(is_number(x) and math.isfinite(x)
                                            for x in value)):
        p.add(where, f"expected a list of {count} {what}, found {describe(value)}")
        return None
    if len(value) != count:
        p.add(where, f"expected {count} values ({what}), found {len(value)}")
        return None
    if value[0] <= 0:
        p.add(where, f"expected positive, strictly increasing values, found first value "
              f"{value[0]!r}")
        return None
    for i in range(1, count):
        if value[i] <= value[i - 1]:
            p.add(where, f"expected positive, strictly increasing values, found "
                  f"{value[i]!r} (index {i}, from 0) after {value[i - 1]!r}")
            return None
    return np.asarray(value, dtype=float)


def read_exponent(p, table, key, where, count, default):
    """A number or a list of ``count`` numbers."""
    if key not in table:
        return default
    value = table[key]
    if is_number(value) and math.isfinite(value):
        return float(value)
    if (isinstance(value, list) and len(value) == count
        and all(is_number(x) and math.isfinite(x) for x in value)):
        return np.asarray(value, dtype=float)
    p.add(key_path(where, key), f"expected a number or a list of {count} numbers, found "
          f"{describe(value)}")
    return None
