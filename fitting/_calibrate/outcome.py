"""How a Levenberg-Marquardt fit ended: an enumeration derived from :class:`jaxtube.RESULTS`
(the engine's codes 0-3 come first and are not used by the fit)."""

from __future__ import annotations

import jaxtube as jt


class FitOutcome(jt.RESULTS):
    """Why the optimiser stopped (its message is ``Convergence.message``)."""

    gradient_small = "gradient below tolerance"
    damping_exhausted = "no further decrease possible (damping exhausted)"
    step_small = "step below tolerance"
    decrease_small = "decrease of the loss below tolerance"
    iterations_exhausted = "maximum number of iterations reached"
    stagnated = ("the loss stagnated: chi^2 fell by less than stall_chi2 over the last "
                 "stall_window iterations (statistically nothing)")
    back_on_bound = ("back on the bound of the watched coordinates (stop_on_bound), held there "
                     "by the active set: a start away from it that found no other basin")


def ending(outcome) -> tuple[str, bool]:
    """``(message, converged)`` of a :class:`FitOutcome` item: every ending but the
    iteration cap is convergence (stagnation is: chi^2 no longer changes by a statistically
    meaningful amount)."""
    return FitOutcome[outcome], bool(outcome != FitOutcome.iterations_exhausted)
