"""One table of the units that jaxtube and its workbench read and write.

Inside jaxtube everything is SI; units appear only in user-facing names (spec keys such as
``pressure_bar``, data columns such as ``force_kN``). :data:`UNITS` maps a physical
quantity to its accepted unit suffixes and each suffix to the exact decimal factor to SI
(``value_SI = value * factor``), in the order in which messages list them (the usual unit
first). :func:`unit_factor` is the lookup, with an error that names what is accepted.

Factors are :class:`decimal.Decimal` so that a reader can convert a written decimal
exactly (a power of ten times the shortest repr of a float64 reads back bit for bit);
:func:`unit_factor` gives the float64 of the same factor.
"""

from __future__ import annotations

import decimal
from collections.abc import Mapping
from types import MappingProxyType

_TABLE: dict[str, dict[str, str]] = {
    "pressure": {"bar": "1E+5", "kPa": "1E+3", "Pa": "1"},
    "length": {"m": "1", "mm": "1E-3"},
    "force": {"N": "1", "kN": "1E+3"},
    "mass": {"kg": "1", "g": "1E-3"},
}

UNITS: Mapping[str, Mapping[str, decimal.Decimal]] = MappingProxyType({
    quantity: MappingProxyType({unit: decimal.Decimal(factor) for unit, factor in units.items()})
    for quantity, units in _TABLE.items()
})
"""``{quantity: {unit suffix: exact factor to SI}}``, read-only."""


def unit_factor(quantity: str, unit: str) -> float:
    """Factor from ``unit`` to SI for ``quantity`` (``value_SI = value * factor``).

    ``unit_factor("pressure", "bar") == 1e5``. Raises ``ValueError`` naming the accepted
    quantities or units when either is unknown.
    """
    if quantity not in UNITS:
        raise ValueError(f"unknown quantity {quantity!r}; expected one of "
                         f"{', '.join(UNITS)}")
    units = UNITS[quantity]
    if unit not in units:
        raise ValueError(f"unknown unit {unit!r} for {quantity}; accepted: "
                         f"{', '.join(units)}")
    return float(units[unit])
