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


def ending(outcome) -> tuple[str, bool]:
    """``(message, converged)`` of a :class:`FitOutcome` item: every ending but the
    iteration cap is convergence."""
    return FitOutcome[outcome], bool(outcome != FitOutcome.iterations_exhausted)
