"""The fit: Levenberg-Marquardt from one or several starts on a :class:`FitProblem`, and the
:class:`FitResult` of the best optimum (method: :mod:`fitting._calibrate.problem`)."""

from __future__ import annotations

import dataclasses
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
    (estimates, uncertainties, identifiability, RMSE, report).

    The effects' free parameters start at their typical size, not at their null: a null on a
    bound (a stiffness, a compliance, a mass cannot be negative) stalls projected steps. With
    ``options.hold_undetermined`` (default) the coordinates the optimum leaves undetermined
    (infinite standard error: the data do not see them, so the optimiser only drifts along
    them) are held at the physics-based first guess, effects at their null, and the rest is
    refitted from the optimum; ``convergence.held`` and the identifiability sentences say
    which (the diagnosis holds them in the same way)."""
    options = options or FitOptions()
    _check_options(options)
    problem = make_problem(data, scaling, rig, options, initial, effects)
    guess = np.array(problem.base, float)  # the physics-based first guess, effects at null
    start = np.array(guess)
    for effect in problem.effects:
        for parameter in effect.parameters:
            name = f"{effect.name}.{parameter.name}"
            i = problem.names.index(name)
            if name not in options.fixed:
                start[i] = float(np.clip(parameter.typical, problem.lower[i], problem.upper[i]))
    result = fit_problem(dataclasses.replace(problem, base=start), options)
    if options.hold_undetermined:
        result = _hold_undetermined(result, guess, options)
    return result


#: Rounds of holding: the refit after holding may leave another coordinate undetermined.
HOLD_ROUNDS = 2


def _hold_undetermined(result: FitResult, guess: np.ndarray, options: FitOptions) -> FitResult:
    """Hold the coordinates ``result`` leaves undetermined at ``guess`` and refit the rest
    from the optimum (:func:`fit`); unchanged when every or no coordinate is undetermined."""
    problem = result.problem
    held: list[str] = []
    why = result.identifiability  # the first fit's words on what the data do not determine
    for _ in range(HOLD_ROUNDS):
        undetermined = [name for name, se in zip(result.problem.free_names,
                                                 result.free_standard_errors)
                        if not math.isfinite(se)]
        if not undetermined or len(undetermined) == len(result.problem.free_names):
            break
        held += undetermined
        vector = np.array(result.vector, float)
        for name in undetermined:
            vector[problem.names.index(name)] = guess[problem.names.index(name)]
        kept = [n for n in result.problem.free_names if n not in undetermined]
        seconds, iterations = result.convergence.seconds, result.convergence.iterations
        evaluations = result.convergence.evaluations
        result = fit_problem(result.problem.with_free(kept, vector), options)
        convergence = dataclasses.replace(
            result.convergence, held=tuple(held),
            seconds=result.convergence.seconds + seconds,
            iterations=result.convergence.iterations + iterations,
            evaluations=result.convergence.evaluations + evaluations,
            solver_calls=(result.convergence.evaluations + evaluations) * len(problem.data))
        words = (f"Held at the physics-based first guess (effects at their null value): "
                 f"{', '.join(held)}; the data do not determine them, so a fit would only "
                 "drift along them.",) + tuple(why)
        parameters = tuple(
            dataclasses.replace(p, standard_error=math.inf, fixed=False, identified=False)
            if p.name in held else p for p in result.parameters)
        result = dataclasses.replace(
            result, convergence=convergence, parameters=parameters,
            identifiability=words + tuple(w for w in result.identifiability if w not in why))
    return result


def _check_options(options: FitOptions) -> None:
    if options.loss not in ("linear", "huber"):
        raise ValueError(f"loss must be 'linear' or 'huber', got {options.loss!r}")
    if options.multistart < 1:
        raise ValueError(f"multistart must be >= 1, got {options.multistart}")


def perturbed_starts(problem: FitProblem, count: int, seed: int) -> list[np.ndarray]:
    """``count`` starts about ``problem.base`` for a multistart fit, each an array of the
    free coordinates' values: every scale (``log a``, ``.A``) moved by a normal step of sd
    0.5 (a factor about 1.6), every other coordinate by one of sd 0.2; the same ``seed``
    gives the same starts (the fit clips them into the box)."""
    x0 = problem.base[np.asarray(problem.free_index)]
    rng = np.random.default_rng(seed)
    scales = np.array([n.endswith(".A") for n in problem.free_names])
    return [x0 + np.where(scales, 0.5 * rng.standard_normal(x0.size),
                          0.2 * rng.standard_normal(x0.size)) for _ in range(count)]


def fit_problem(problem: FitProblem, options: FitOptions | None = None, description: str =
                "fit (LM iterations)"):
    """Levenberg-Marquardt on a set-up :class:`FitProblem` from its ``base`` vector (the free
    coordinates start there; e.g. ``problem.with_free(names, previous.vector)`` refits from
    a previous optimum with more coordinates free, on the same compiled model)."""
    options = options or FitOptions()
    _check_options(options)
    x0 = problem.base[np.asarray(problem.free_index)]
    starts = [x0] + perturbed_starts(problem, options.multistart - 1, options.seed)
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
