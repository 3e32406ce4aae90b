"""Status of each quantity at each sweep point: an enumeration derived from
:class:`jaxtube.RESULTS` (0 = computed; the solver's own codes 1-3 are inherited and unused
here, since a failed solve is reported as ``solver_failed`` with the solver's code beside it).
"""

from __future__ import annotations

import jaxtube as jt

from .._codes import code


class SweepStatus(jt.RESULTS):
    """Outcome of one quantity (wrinkling load, collapse load, tip deflection) at one point."""

    solver_failed = "equilibrium solve failed"
    moment_missed = "load iteration did not reach the target root moment"
    no_regime = "not applicable: the law has no such regime below 1e6 1/m"
    unreachable = ("not applicable: the root joint reaches this curvature only with its "
                   "segment turned past the vertical (no equilibrium under a downward tip "
                   "load)")


STATUS_OK = code(SweepStatus.successful)
STATUS_SOLVER_FAILED = code(SweepStatus.solver_failed)
STATUS_MOMENT_MISSED = code(SweepStatus.moment_missed)
STATUS_NO_REGIME = code(SweepStatus.no_regime)
STATUS_UNREACHABLE = code(SweepStatus.unreachable)
#: ``{status code: message}`` of :class:`SweepStatus`.
STATUS_MESSAGES = jt.result_messages(SweepStatus)
