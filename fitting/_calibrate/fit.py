"""The fit: Levenberg-Marquardt from one or several starts on a :class:`FitProblem`, and the
:class:`FitResult` of the best optimum (method: :mod:`fitting._calibrate.problem`)."""

from __future__ import annotations

import math
import time

import numpy as np

from .._bench.rig import CantileverRig
from .._bench.scaling import PivotScaling
from .._data import MeasuredData
from .problem import (
    Convergence,
    FitError,
    FitOptions,
    FitProblem,
    _levenberg_marquardt,
    make_problem,
)
from .result import FitResult


def fit(data: MeasuredData, scaling: PivotScaling | None = None,
        rig: CantileverRig | None = None, options: FitOptions | None = None,
        initial: np.ndarray | None = None, effects: tuple = ()):
    """Fit the pivot scaling (and the parameters of ``effects``, :class:`fitting.Effect`
    subclasses) to every curve of ``data`` at once; returns a :class:`fitting.FitResult`
    (estimates, uncertainties, identifiability, RMSE, report)."""
    options = options or FitOptions()
    _check_options(options)
    problem = make_problem(data, scaling, rig, options, initial, effects)
    return fit_problem(problem, options)


def _check_options(options: FitOptions) -> None:
    if options.loss not in ("linear", "huber"):
        raise ValueError(f"loss must be 'linear' or 'huber', got {options.loss!r}")
    if options.multistart < 1:
        raise ValueError(f"multistart must be >= 1, got {options.multistart}")


def fit_problem(problem: FitProblem, options: FitOptions | None = None, description: str =
                "fit (LM iterations)"):
    """Levenberg-Marquardt on a set-up :class:`FitProblem` from its ``base`` vector (the free
    coordinates start there; e.g. ``problem.with_free(names, previous.vector)`` refits from
    a previous optimum with more coordinates free, on the same compiled model)."""
    options = options or FitOptions()
    _check_options(options)
    x0 = problem.base[np.asarray(problem.free_index)]
    rng = np.random.default_rng(options.seed)
    starts = [x0] + [
        x0 + np.where(np.array([n.endswith(".A") for n in problem.free_names]),
                      0.5 * rng.standard_normal(x0.size), 0.2 * rng.standard_normal(x0.size))
        for _ in range(options.multistart - 1)]
    bar = None
    if options.progress:
        from tqdm.auto import tqdm  # lazy: only a fit that shows progress needs it
        bar = tqdm(total=options.max_iterations * len(starts), desc=description,
                   unit="it", leave=False)
    t0 = time.perf_counter()
    best, costs, totals = None, [], {"evaluations": 0, "iterations": 0}
    try:
        for start in starts:
            try:
                x, cost, report = _levenberg_marquardt(problem, start, options, bar)
            except FitError:
                if len(starts) == 1:
                    raise
                costs.append(math.inf)
                continue
            costs.append(cost)
            totals["evaluations"] += report["evaluations"]
            totals["iterations"] += report["iterations"]
            if best is None or cost < best[1]:
                best = (x, cost, report)
    finally:
        if bar is not None:
            bar.close()
    if best is None:
        raise FitError("every start failed: the equilibrium solves did not converge")
    x, cost, report = best
    convergence = Convergence(
        converged=report["converged"], message=report["message"],
        iterations=totals["iterations"], evaluations=totals["evaluations"],
        solver_calls=totals["evaluations"] * len(problem.data),
        seconds=time.perf_counter() - t0, starts=len(starts), start_costs=tuple(costs))
    return FitResult.from_optimum(problem, x, report, convergence)
