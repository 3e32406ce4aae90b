"""Integer codes of the workbench's outcome enumerations.

Every outcome of the workbench (the sweep's statuses, the planar route's results, the fit's
ending) is an ``equinox.Enumeration`` derived from the engine's one vocabulary,
:class:`jaxtube.RESULTS`, whose codes 0-3 come first (0 is success); messages come from the
enumeration (:func:`jaxtube.result_messages`). Arrays computed under ``jit`` hold the codes
as integers, which this module reads off the items.
"""

from __future__ import annotations

import equinox as eqx


def code(item: eqx.Enumeration) -> int:
    """The integer code of an enumeration item: its index in definition order, the parent
    enumeration's items first (``code(jaxtube.RESULTS.successful) == 0``)."""
    return int(item._value)  # equinox keeps the index private; it is read here only
