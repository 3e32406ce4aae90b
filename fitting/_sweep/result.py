"""The settings of a sweep (they fix its compiled program) and its result, with the failures
in words (method: :mod:`fitting._sweep.sweep`)."""

from __future__ import annotations

import equinox as eqx
import numpy as np

import jaxtube as jt

from .._bench.rig import DEFAULT_SEGMENTS
from .status import (
    STATUS_MESSAGES,
    STATUS_MOMENT_MISSED,
    STATUS_OK,
    STATUS_SOLVER_FAILED,
)

#: Solver of the generic route: the package's tolerances, fewer Newton steps (a point that
#: needs more has failed; under ``vmap`` a failing point holds up its whole chunk).
SWEEP_SOLVER = jt.NewtonKKT(max_steps=40)


class SweepSettings(eqx.Module):
    """Static settings of a sweep (they fix the compiled program).

    Attributes:
        segments: rigid segments of the cantilever (default 12, within about 0.1 % of the
            elastica; tests/test_beam_references.py).
        planar_wrinkling_steps, planar_collapse_steps, planar_deflection_steps: most
            Newton steps of each planar solve (planar route; it stops when converged).
            Over 0.1-0.5 bar, r = 30-150 mm, L = 0.5-2 m and tip loads 0.1-500 N (20,000
            random specimens per law) the tension-field law (E t = 150 kN/m and 5 MN/m)
            and the spline through it needed at most 3, 7 and 14 steps; Breukels' 2011
            law, at radii below about 41 mm where its fit is out of range and its initial
            stiffness nearly zero, up to 13 and 11 steps for a few points (with these
            defaults 6 of its 18,756 wrinkling loads, 1 in 3,000, are reported as not
            converged, 1 of them also with 40 steps; raise the steps for such laws).
        planar_tolerance: largest accepted equilibrium residual of a planar solve, relative
            to the reference moment (planar route).
        wrinkling_iterations, collapse_iterations: solves of each load iteration (generic
            route).
        tip_steps: load steps to the given tip load (generic route).
        moment_tolerance: largest accepted ``|M_root / M_target - 1|`` (both routes).
        chunk_size: points per compiled call (rounded up to a multiple of the devices).
        solver: the equilibrium solver of the generic route.
    """

    segments: int = DEFAULT_SEGMENTS
    planar_wrinkling_steps: int = 10
    planar_collapse_steps: int = 12
    planar_deflection_steps: int = 20
    planar_tolerance: float = 1e-10
    wrinkling_iterations: int = 3
    collapse_iterations: int = 6
    tip_steps: int = 4
    moment_tolerance: float = 1e-6
    chunk_size: int = 512
    solver: jt.NewtonKKT = SWEEP_SOLVER


class SweepResult(eqx.Module):
    """The outcome of :func:`sweep`. Every array has the broadcast shape ``S`` of the inputs.

    Attributes:
        pressure [Pa], radius [m], length [m], tip_load [N]: the specimens.
        initial_stiffness: ``EI0`` [N m^2].
        wrinkling_moment, collapse_moment: the law's regime-boundary moments [N m] (NaN if
            the law has no such regime).
        wrinkling_load, collapse_load: dead tip loads [N] (NaN where not available).
        tip_deflection: downward tip displacement at ``tip_load`` [m] (NaN where failed).
        wrinkling_status, collapse_status, deflection_status: codes of
            :data:`STATUS_MESSAGES` (int).
        wrinkling_solver_result, collapse_solver_result, deflection_solver_result: the
            worst ``jaxtube.RESULT_MESSAGES`` code of the solves of each quantity (planar
            route: 0 converged, 1 not converged in the fixed steps, 3 non-finite).
        wrinkling_mismatch, collapse_mismatch: ``|M_root / M_target - 1|`` at the reported
            load.
        iterations: Newton steps of all solves of the point (planar route: of the fixed
            steps, those that started from a residual above ``planar_tolerance``).
        settings: the :class:`SweepSettings`.
        devices: devices the grid was sharded over.
        seconds: wall time of the evaluation (with compilation).
        route: ``"planar"`` or ``"generic"`` (module docstring).
    """

    pressure: np.ndarray
    radius: np.ndarray
    length: np.ndarray
    tip_load: np.ndarray
    initial_stiffness: np.ndarray
    wrinkling_moment: np.ndarray
    collapse_moment: np.ndarray
    wrinkling_load: np.ndarray
    collapse_load: np.ndarray
    tip_deflection: np.ndarray
    wrinkling_status: np.ndarray
    collapse_status: np.ndarray
    deflection_status: np.ndarray
    wrinkling_solver_result: np.ndarray
    collapse_solver_result: np.ndarray
    deflection_solver_result: np.ndarray
    wrinkling_mismatch: np.ndarray
    collapse_mismatch: np.ndarray
    iterations: np.ndarray
    settings: SweepSettings = eqx.field(static=True)
    devices: int = eqx.field(static=True)
    seconds: float = eqx.field(static=True)
    route: str = eqx.field(static=True, default="planar")

    @property
    def failed(self) -> np.ndarray:
        """bool ``S``: some quantity of the point failed (not applicable, i.e.
        ``STATUS_NO_REGIME`` or ``STATUS_UNREACHABLE``, does not count)."""
        bad = (STATUS_SOLVER_FAILED, STATUS_MOMENT_MISSED)
        return (np.isin(self.wrinkling_status, bad) | np.isin(self.collapse_status, bad)
                | np.isin(self.deflection_status, bad))

    @property
    def failed_count(self) -> int:
        return int(self.failed.sum())

    def failure_reasons(self) -> np.ndarray:
        """str ``S``: "ok", or every problem of the point in words (semicolon-separated)."""
        flat = []
        columns = [
            ("wrinkling load", self.wrinkling_status, self.wrinkling_solver_result,
             self.wrinkling_mismatch),
            ("collapse load", self.collapse_status, self.collapse_solver_result,
             self.collapse_mismatch),
            ("tip deflection", self.deflection_status, self.deflection_solver_result, None),
        ]
        for i in range(self.pressure.size):
            parts = []
            for name, status, solver_result, mismatch in columns:
                code = int(status.flat[i])
                if code == STATUS_OK:
                    continue
                text = f"{name}: {STATUS_MESSAGES[code]}"
                if code == STATUS_SOLVER_FAILED:
                    text += f" ({jt.RESULT_MESSAGES[int(solver_result.flat[i])]})"
                if code == STATUS_MOMENT_MISSED:
                    text += (f" (relative mismatch {float(mismatch.flat[i]):.2g} > "
                             f"{self.settings.moment_tolerance:g})")
                parts.append(text)
            flat.append("; ".join(parts) if parts else "ok")
        return np.array(flat, dtype=object).reshape(self.pressure.shape)
