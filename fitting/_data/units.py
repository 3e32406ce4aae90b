"""Units of the measurement file's columns, from the engine's one table (:data:`jaxtube.UNITS`).

Measurement files name their units in the column names (``pressure_bar``, ``radius_mm``).
Each column measures a physical quantity of the engine's table (radius, length and deflection
are lengths); the factors to SI are the table's exact decimals, so a conversion is exact in
decimal before rounding to float64.
"""

from __future__ import annotations

import decimal
from collections.abc import Mapping
from types import MappingProxyType

import jaxtube as jt

#: Column quantity -> the physical quantity of :data:`jaxtube.UNITS` it is measured in.
COLUMN_QUANTITY = {
    "pressure": "pressure",
    "radius": "length",
    "length": "length",
    "deflection": "length",
    "force": "force",
}
QUANTITIES = tuple(COLUMN_QUANTITY)
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
#: Column quantity -> accepted unit suffixes, in the order messages list them: the default
#: unit first, then the others in the engine's table order.
COLUMN_UNITS: Mapping[str, tuple[str, ...]] = MappingProxyType({
    quantity: (DEFAULT_UNITS[quantity],
               *(unit for unit in jt.UNITS[physical] if unit != DEFAULT_UNITS[quantity]))
    for quantity, physical in COLUMN_QUANTITY.items()
})
#: Factors from SI to the units that tables, figures and messages show.
BAR_PER_PA = 1 / jt.unit_factor("pressure", "bar")
MM_PER_M = 1 / jt.unit_factor("length", "mm")
# 28 significant digits: exact for any float64 repr (<= 17 digits) times a power of ten.
DECIMAL_CONTEXT = decimal.Context(prec=28)


def _factor(quantity: str, unit: str) -> decimal.Decimal:
    return jt.UNITS[COLUMN_QUANTITY[quantity]][unit]


def accepted_columns(quantity: str) -> str:
    return ", ".join(f"{quantity}_{unit}" for unit in COLUMN_UNITS[quantity])


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
        if quantity not in COLUMN_UNITS:
            raise ValueError(f"unknown quantity {quantity!r} in units; expected one of "
                             f"{', '.join(QUANTITIES)}")
        if unit not in COLUMN_UNITS[quantity]:
            raise ValueError(f"unknown unit {unit!r} for {quantity}; accepted: "
                             f"{', '.join(COLUMN_UNITS[quantity])}")
        chosen[quantity] = unit
    return chosen
