"""A campaign's cases solved: one compiled program per route, shared by every case and value.

Routes (``CampaignCase.route``), each from the undeformed shape:

- ``"gravity"``: gravity alone in the first solve (the later ones start at the equilibrium
  and take no Newton step), the lines' blend at the model's width;
- ``"stages"``: gravity and loads stepped through ``[hang] load_stages``
  (:func:`jaxtube.hang_kite`), the first stage's blend ``first_stage_tension_smoothing``,
  the later ones the model's, so the equilibrium reported is the model's;
- ``"drive"``: a hanging mass: its node held where the model file has it while gravity
  acts (the mass taken off), then driven along gravity until the actuator carries its
  weight (:func:`jaxtube.drive_to_dead_load` from the undeformed shape), then the
  dead-load solve from there: the equilibrium reported. Force control fails on the V3
  kite's centre loads (experiments/README.md); a gravity hang before the drive took more
  Newton steps in all (``docs/performance.md``).

The programs take the parameters (so every pressure, load and model value) and, for the
first two routes, the stages and blend widths as traced arguments: each is compiled once per
process (:class:`CaseSolver`), ahead of the first timed solve, so every ``seconds`` is warm.
"""

from __future__ import annotations

import dataclasses
import json
import threading
import time

import jax
import jax.numpy as jnp
import numpy as np

import jaxtube as jt

from .file import Campaign, CampaignCase
from .kite import (
    import_campaign_case,
    model_value,
    search_coordinates,
    values_from_search,
    with_model_values,
    with_values,
)
from .model import KiteModel


@dataclasses.dataclass(frozen=True, eq=False)
class CaseSolution:
    """One case solved.

    Attributes:
        case: the case.
        imported: the imported kite with the case's loads and the model's values.
        solution: the equilibrium (a :class:`jaxtube.Solution` with a leading stage axis;
            the last entry is the case's).
        positions: ``[N, 3]`` node positions [m] in the model file's numbering and frame.
        converged: the equilibrium reported converged.
        newton_iterations: per solve (the stages; a drive's first controlled solve and its
            dead-load solve, its steps in ``drive``).
        stage_converged: per solve, likewise.
        drive: the drive's record (route ``"drive"``), else ``None``.
        hang: the route in words.
        seconds: the warm solve [s]; compile_seconds: its program's compilation [s].
    """

    case: CampaignCase
    imported: jt.KiteFemImport
    solution: jt.Solution
    positions: np.ndarray
    converged: bool
    newton_iterations: list
    stage_converged: list
    drive: dict | None
    hang: str
    seconds: float
    compile_seconds: float


#: Newton steps a warm start may take before :meth:`CaseSolver.tangents` gives it up for the
#: case's route: about what the route takes from the undeformed shape (60 to 230 steps, 1 to
#: 4 s on the V3 cases), so a warm start far from its equilibrium costs no more than the
#: route itself (``experiments/v3_shape_fit.py``).
WARM_NEWTON_STEPS = 100

# Compiled programs of this process, shared by every CaseSolver of the same kite and hang
# schedule (a V3 program takes a minute or more to compile): key -> (program, seconds).
_PROGRAMS: dict = {}


_COMPILING = threading.Lock()


def _compiled(key, function, *arguments):
    """``(program, compile seconds)`` of ``function`` at ``arguments``, compiled once per
    process under ``key`` (cases solved in threads wait for one compilation)."""
    with _COMPILING:
        if key not in _PROGRAMS:
            started = time.perf_counter()
            program = jax.jit(function).lower(*arguments).compile()
            _PROGRAMS[key] = (program, time.perf_counter() - started)
    return _PROGRAMS[key]


class CaseSolver:
    """Solves a campaign's cases, compiling each route's program once per process (shared
    by every solver of the same model file, suspension and hang schedule).

    ``tangent_values``: when given, :meth:`tangents` always differentiates with respect to
    these values (a superset of every ``names`` it is asked for) and returns the columns
    asked for, so that fits of different sets of values (a diagnosis) share one compiled
    program per route.

    ``warm_starts``: :meth:`tangents` starts each case from its last converged equilibrium
    (of whatever values it was last solved with) in one full-load solve of at most
    ``WARM_NEWTON_STEPS`` Newton steps (its own program, shared by every route), and falls
    back to the case's own route from the undeformed shape when that does not converge.
    :meth:`solve` always takes the route.
    ``record`` lists every :meth:`tangents` call: ``{"case", "warm", "newton_iterations",
    "seconds", "converged", "result"}`` (the last solve's outcome in words,
    ``jaxtube.RESULT_MESSAGES``; a fallback adds both solves)."""

    def __init__(self, campaign: Campaign, tangent_values=None, warm_starts: bool = True):
        self.campaign = campaign
        self.solver = jt.NewtonKKT(max_steps=campaign.hang.max_newton_steps)
        self.warm_solver = dataclasses.replace(self.solver, max_steps=WARM_NEWTON_STEPS)
        self.tangent_values = None if tangent_values is None else tuple(tangent_values)
        self.warm_starts = warm_starts
        self.record: list = []
        self._last: dict = {}
        self._plain: dict = {}

    def _schedule(self, case: CampaignCase, model_blend: float):
        stages = self.campaign.hang.load_stages
        if case.route == "gravity":
            return (1.0,) * len(stages), (model_blend,) * len(stages)
        first = self.campaign.hang.first_stage_tension_smoothing
        return stages, ((model_blend if first is None else first),) + \
            (model_blend,) * (len(stages) - 1)

    def _route(self, imported: jt.KiteFemImport, case: CampaignCase, start=None):
        """``(key, run, arguments)``: the case's route as a function of the parameters (and,
        for a hang, the stages, blend widths and start), its cache key and its arguments.
        ``start`` (a :class:`jaxtube.HangStart`): instead of the route, one solve at full
        gravity and loads and the model's blend from there, of at most
        ``WARM_NEWTON_STEPS`` Newton steps (one program for every route)."""
        drive_node = int(imported.node_index[case.loads[0].node]) \
            if case.route == "drive" and start is None else None
        route = "warm" if start is not None else "drive" if drive_node is not None else "hang"
        key = (str(self.campaign.kite_fem.path), self.campaign.suspension, self.campaign.hang,
               route, type(imported.params.bending_laws[0]).__name__, drive_node)
        structure, hang = imported.structure, self.campaign.hang
        solver = self.warm_solver if start is not None else self.solver
        if drive_node is None:
            def run(params, load_factors, blends, start, warm):
                cold = jt.undeformed_start(structure, params)
                begin = jax.tree_util.tree_map(lambda w, c: jnp.where(warm, w, c), start, cold)
                return jt.hang_kite(structure, params, solver=solver, load_factors=load_factors,
                                    tension_smoothing=blends, start=begin)

            blend = float(imported.params.elements.tension_smoothing)
            if start is None:
                schedule = self._schedule(case, blend)
                start, warm = jt.undeformed_start(structure, imported.params), False
            else:
                schedule, warm = ((1.0,), (blend,)), True
            return key, run, (imported.params, *map(jnp.asarray, schedule), start,
                              jnp.asarray(warm))

        def run(params):
            return jt.drive_to_dead_load(structure, params, drive_node, params.gravity,
                                         solver=solver, steps=hang.drive_steps,
                                         max_increment=hang.drive_increment_m)

        return key, run, (imported.params,)

    def tangents(self, case: CampaignCase, model: KiteModel, names) -> tuple:
        """The case's equilibrium and its tangents with respect to ``model``'s values
        ``names`` (``"bending_scale"``, ``"rest_length_factors.SET"``,
        ``"point_masses_kg.POINT"``, ...: :func:`fitting.model_value`) in their search
        coordinates (:func:`fitting.search_coordinates`: the logarithm of a factor, a mass or
        an offset as it is), by forward mode through the solve (implicit function theorem;
        a drive only supplies the start of the last solve). Returns ``(positions [N, 3] [m],
        tangents [N, 3, k] [m per unit coordinate], converged)`` in the model file's
        numbering (held nodes do not move). One more compiled program per route and set of
        names (per route only, with ``tangent_values``), and one for warm starts
        (``warm_starts``, shared by every route)."""
        asked = tuple(names)
        names = asked if self.tangent_values is None else self.tangent_values
        missing = set(asked) - set(names)
        if missing:
            raise ValueError(f"tangents: {sorted(missing)} not among the solver's "
                             f"tangent_values {list(names)}")
        if case.name not in self._plain:  # the same for every value and law form
            self._plain[case.name] = import_campaign_case(self.campaign, case, KiteModel())
        plain = self._plain[case.name]
        theta = jnp.asarray(search_coordinates(names, [model_value(model, n) for n in names]))
        start = self._last.get(case.name) if self.warm_starts else None
        jacobian, x, converged = self._tangent_solve(plain, case, model, names, theta, start)
        if start is not None and not converged:
            jacobian, x, converged = self._tangent_solve(plain, case, model, names, theta,
                                                         None)
        mapped = plain.node_index >= 0
        tangent = np.zeros(plain.model.node_position.shape + (len(names),))
        tangent[mapped] = np.asarray(jacobian)[plain.node_index[mapped]]
        columns = [names.index(name) for name in asked]
        return plain.kite_positions(np.asarray(x)), tangent[..., columns], converged

    def _tangent_solve(self, plain, case, model, names, theta, start):
        """``(jacobian, positions, converged)`` of one solve for :meth:`tangents` (from
        ``start``, or by the case's route when ``None``); keeps the equilibrium as the case's
        next start when it converged."""
        key, run, arguments = self._route(plain, case, start)
        campaign, drive = self.campaign, key[3] == "drive"

        def positions(theta, params, *schedule):
            values = with_values(model, names, values_from_search(names, theta))
            result = run(with_model_values(campaign, params, values, plain), *schedule)
            solution, iterations = _last_solve(result, drive)
            x = solution.node_position[-1]
            return x, (x, solution.converged[-1], iterations, solution.result[-1],
                       jt.restart_from(solution))

        # The program closes over the model's other values and the campaign's named sets:
        # they are part of its key (a program is never reused with other constants), written
        # in sorted order (models that differ only in the order their values were set share
        # a program).
        others = with_values(model, names, [0.0] * len(names)).to_json()
        constants = json.dumps([others, campaign.line_sets, campaign.tube_classes,
                                campaign.points, campaign.gravity.tolist()], sort_keys=True)
        program, _ = _compiled(("tangents", names, constants) + key,
                               jax.jacfwd(positions, has_aux=True), theta, *arguments)
        started = time.perf_counter()
        jacobian, (x, converged, iterations, result, reached) = jax.block_until_ready(
            program(theta, *arguments))
        converged = bool(converged)
        self.record.append({"case": case.name, "warm": start is not None,
                            "newton_iterations": int(iterations),
                            "seconds": time.perf_counter() - started, "converged": converged,
                            "result": jt.RESULT_MESSAGES[int(result)]})
        if converged:
            self._last[case.name] = reached
        return jacobian, x, converged

    def solve(self, case: CampaignCase, model: KiteModel) -> CaseSolution:
        """Solve ``case`` with ``model``'s values by its route from the undeformed shape
        (compiled ahead, then timed warm)."""
        imported = import_campaign_case(self.campaign, case, model)
        key, run, arguments = self._route(imported, case)
        program, compile_seconds = _compiled(key, run, *arguments)
        started = time.perf_counter()
        result = jax.block_until_ready(program(*arguments))
        seconds = time.perf_counter() - started
        if case.route != "drive":
            solution, drive = result, None
            iterations = np.asarray(result.iterations).tolist()
            stage_converged = np.asarray(result.converged).tolist()
            factors, blends = arguments[1:3]
            words = (f"load factors {np.asarray(factors).tolist()} ({case.route}), the "
                     f"lines' blend widths {np.asarray(blends).tolist()}")
        else:
            driven = result
            iterations = [int(driven.start.iterations), int(driven.equilibrium.iterations)]
            stage_converged = [bool(driven.start.converged),
                               bool(driven.equilibrium.converged)]
            solution = jax.tree_util.tree_map(lambda x: x[None], driven.equilibrium)
            taken = int(driven.steps_taken)
            accepted = np.asarray(driven.path.converged)[:taken]
            drive = {"reached": bool(driven.reached),
                     "target_force_N": float(driven.target_force),
                     "control_displacement_m": np.asarray(
                         driven.path.control_displacement)[:taken][accepted].tolist(),
                     "control_force_N": np.asarray(
                         driven.path.control_force)[:taken][accepted].tolist(),
                     "newton_iterations": np.asarray(driven.path.iterations)[:taken].tolist(),
                     "step_converged": accepted.tolist()}
            hang = self.campaign.hang
            words = (f"node {case.loads[0].node} held where the model file has it under "
                     f"gravity (the mass taken off), then driven along gravity until it "
                     f"carries the mass (jaxtube.drive_to_dead_load, at most "
                     f"{hang.drive_steps} steps of at most {hang.drive_increment_m} m), then "
                     f"the dead-load solve")
        positions = imported.kite_positions(np.asarray(solution.node_position)[-1])
        return CaseSolution(case, imported, solution, positions,
                            bool(np.asarray(solution.converged)[-1]), iterations,
                            stage_converged, drive, words, seconds, compile_seconds)


def _last_solve(result, drive: bool):
    """``(solution with a leading stage axis, Newton iterations in all)`` of a route's
    result (a hang's stages, or a drive's :class:`jaxtube.DrivenEquilibrium`: its dead-load
    solve)."""
    if not drive:
        return result, jnp.sum(result.iterations)
    solution = jax.tree_util.tree_map(lambda x: x[None], result.equilibrium)
    return solution, (result.start.iterations + jnp.sum(result.path.iterations)
                      + result.equilibrium.iterations)
