"""Measured force-deflection curves: loading, validation and saving.

File format
-----------
A measurement file is a long-format CSV (UTF-8, an optional byte-order mark is ignored),
one row per measured point, with a header line::

    curve,setup,pressure_bar,radius_m,length_m,deflection_mm,force_N
    shear-1,cantilever_tip,0.15,0.075,0.6,1.725,1.7114
    shear-1,cantilever_tip,0.15,0.075,0.6,3.514,3.9632
    ...

Columns (in any order):

- ``curve``: the curve name (non-empty text). All rows with the same name form one curve,
  which needs at least 2 points; rows of one curve need not be adjacent.
- ``setup``: the test setup, ``kind`` or ``kind:arguments``. Known kinds:

  - ``cantilever_tip``: horizontal tube clamped at the root, dead vertical tip load;
    the deflection is the vertical tip displacement from the unloaded shape.

- One column per quantity, its unit given by the suffix; values are converted to SI
  (exactly one column per quantity; the factors are those of :data:`jaxtube.UNITS`):

  - pressure (gauge, > 0) [Pa]: ``pressure_bar``, ``pressure_kPa`` or ``pressure_Pa``;
  - radius (> 0) [m]: ``radius_m`` or ``radius_mm``;
  - length (> 0) [m]: ``length_m`` or ``length_mm``;
  - deflection (any finite value) [m]: ``deflection_mm`` or ``deflection_m``;
  - force (any finite value) [N]: ``force_N`` or ``force_kN``.

  Pressure, radius, length and setup describe the specimen and must be the same on every
  row of a curve. Deflection and force may take either sign (a bench test may push both
  ways); repeated deflections within a curve are allowed.
- Optional ``weight``: a positive finite per-point weight for the fit (1 when absent).
- Optional ``note``: free text, kept with the point and otherwise ignored.

Any other column is an error. Unit conversion is exact in decimal before rounding to
float64, so ``0.15`` bar, ``15`` kPa and ``15000`` Pa give the same float64 value.

Errors
------
:func:`load_measurements` checks the whole file in one pass and raises a single
:class:`DataError` (a :class:`ValueError`) listing every problem, one per line, each
naming the file, the line (1-based, header = line 1) and the column, and saying what was
expected and what was found. The structured list is in ``DataError.problems``.

Adding a setup kind
-------------------
Setups are parsed through the registry ``_SETUP_KINDS`` (:mod:`fitting._data.setups`): a new
kind (e.g. ``spec:path/to/structure.toml:node``) is one entry, a :class:`_SetupKind` with a
description and a function that checks the text after ``kind:``.
"""

from __future__ import annotations

from .._tables import DataError, DataProblem
from .curves import MeasuredCurve, MeasuredData
from .load import load_measurements

__all__ = ["DataError", "DataProblem", "MeasuredCurve", "MeasuredData", "load_measurements"]
