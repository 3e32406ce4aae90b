"""One vocabulary of success and failure for every solve in jaxtube and the workbench.

:class:`RESULTS` is an ``equinox.Enumeration`` (the optimistix pattern): the Newton-KKT solver
returns one of its items as an integer code, and the workbench's own outcomes (sweep statuses,
the planar route, fit convergence) are enumerations that *derive* from it (``class
SweepStatus(RESULTS)``), so a solver code keeps its meaning wherever it travels. The integer
codes below are the ones the documentation names and must not change order:

    0 converged, 1 Newton step cap, 2 line search failed, 3 non-finite values.
"""

from __future__ import annotations

import equinox as eqx


class RESULTS(eqx.Enumeration):
    """Outcome of an equilibrium solve (integer code = definition order)."""

    successful = "converged"
    max_steps_reached = "did not converge within the maximum number of Newton steps"
    line_search_failed = "line search failed (no decrease of the merit function)"
    nonfinite = "non-finite energy, gradient or Hessian (NaN or inf)"


def result_messages(enumeration: type[eqx.Enumeration]) -> dict[int, str]:
    """``{integer code: message}`` of an enumeration, a derived one's parents' codes first."""
    return dict(enumeration._index_to_message.items() if isinstance(
        enumeration._index_to_message, dict) else enumerate(enumeration._index_to_message))
