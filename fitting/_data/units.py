"""The workbench's one units table: quantity -> unit suffix -> factor to SI.

Measurement files name their units in the column names (``pressure_bar``, ``radius_mm``);
the command line's flags do too (``--pressure-bar``). Every conversion of the workbench goes
through :data:`UNITS`. Factors are held as text and converted with ``decimal.Decimal(str(.))``,
so a conversion is exact in decimal before rounding to float64 whether a factor is a string or
a float: the engine's table can replace this one with a one-line change
(``UNITS = jt.UNITS``).
"""

from __future__ import annotations

import decimal
from collections.abc import Mapping

#: Quantity -> unit suffix -> factor to SI (value_SI = value * factor).
UNITS: Mapping[str, Mapping[str, str | float]] = {
    "pressure": {"bar": "1E+5", "kPa": "1E+3", "Pa": "1"},
    "radius": {"m": "1", "mm": "1E-3"},
    "length": {"m": "1", "mm": "1E-3"},
    "deflection": {"mm": "1E-3", "m": "1"},
    "force": {"N": "1", "kN": "1E+3"},
}
QUANTITIES = tuple(UNITS)
# Specimen quantities: positive, and constant within a curve.
SPECIMEN_QUANTITIES = ("pressure", "radius", "length")
OPTIONAL_COLUMNS = ("weight", "note")
# Units written by default: those of the shared measurement files.
DEFAULT_UNITS = {
    "pressure": "bar",
    "radius": "m",
    "length": "m",
    "deflection": "mm",
    "force": "N",
}
# 28 significant digits: exact for any float64 repr (<= 17 digits) times a power of ten.
DECIMAL_CONTEXT = decimal.Context(prec=28)


def _factor(quantity: str, unit: str) -> decimal.Decimal:
    return decimal.Decimal(str(UNITS[quantity][unit]))


def unit_factor(quantity: str, unit: str) -> float:
    """Factor from ``unit`` to SI for ``quantity`` (``unit_factor("pressure", "bar")`` is
    ``1e5``): ``value_SI = value * factor``."""
    return float(_factor(quantity, unit))


def accepted_columns(quantity: str) -> str:
    return ", ".join(f"{quantity}_{unit}" for unit in UNITS[quantity])


def to_si(value: decimal.Decimal, quantity: str, unit: str) -> float:
    return float(DECIMAL_CONTEXT.multiply(value, _factor(quantity, unit)))


def from_si(value: float, quantity: str, unit: str) -> decimal.Decimal:
    # repr() is the shortest decimal that reads back as `value`; dividing it by a power of
    # ten is exact, so writing and reading back gives the same float64 bit for bit.
    return DECIMAL_CONTEXT.divide(decimal.Decimal(repr(value)), _factor(quantity, unit))


def format_decimal(value: decimal.Decimal) -> str:
    value = value.normalize(DECIMAL_CONTEXT)
    if -7 <= value.adjusted() < 16:
        return format(value, "f")
    return str(value)


def check_units(units: Mapping[str, str] | None) -> dict[str, str]:
    chosen = dict(DEFAULT_UNITS)
    for quantity, unit in (units or {}).items():
        if quantity not in UNITS:
            raise ValueError(
                f"unknown quantity {quantity!r} in units; expected one of {', '.join(UNITS)}"
            )
        if unit not in UNITS[quantity]:
            raise ValueError(
                f"unknown unit {unit!r} for {quantity}; accepted: {', '.join(UNITS[quantity])}"
            )
        chosen[quantity] = unit
    return chosen

