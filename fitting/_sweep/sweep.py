"""Design sweeps: a bending law evaluated on the standard bench cantilever over many specimens.

For every specimen ``(p, r, L)`` (envelope overpressure [Pa], radius [m], length [m]) and a
dead tip load ``F_tip`` [N], :func:`sweep` reports four quantities of the standard bench
cantilever (:class:`fitting.CantileverRig`: a straight tube along +x, clamped at its root,
dead vertical tip load along -z, ``segments`` rigid segments):

- **initial bending stiffness** ``EI0 = dM/dkappa`` at zero curvature [N m^2], the law's own
  initial slope (``AbstractMomentLaw.initial_stiffness``; no solve).
- **wrinkling load** ``F_w`` [N]: the dead tip load at which the clamp (root) joint, the most
  loaded joint of a tip-loaded cantilever, carries the law's *wrinkling moment* ``M_w``. The
  wrinkling moment is the moment at the curvature where the law's regime leaves 0
  (unwrinkled): the onset pivot of a :class:`jaxtube.SplineLaw`, Comer & Levy's
  ``pi p r^3 / 2`` for the :class:`jaxtube.TensionFieldLaw`, ``0.5 M_max`` by this package's
  convention for :class:`jaxtube.EmpiricalBendingLaw2011`. That curvature is found by
  bisection on ``law.regime`` (so any law works), in ``log kappa`` over ``[1e-9, 1e6]`` 1/m.
- **collapse load** ``F_c`` [N]: likewise at the *collapse moment* ``M_c``, where the regime
  becomes 2 (collapsed): the collapse pivot of a spline law; for the tension-field law,
  whose moment only tends to Comer & Levy's ``pi p r^3``, the package's collapsed-regime
  threshold ``0.95 pi p r^3``; ``0.95 M_max`` for the 2011 law.
- **tip deflection** ``v`` [m] at the given load ``F_tip``: the downward tip displacement of
  the force-controlled equilibrium.

**Geometric nonlinearity.** Every load is found from the full large-rotation equilibrium of
the rigid-segment chain, not from the small-deflection estimate ``M / L``: the root moment
of a dead vertical tip load is ``F a_1``, with the lever arm ``a_1 = L - u`` shortened by the
tip's horizontal displacement ``u``.

**Two routes, one model.**

- *Planar route* (a bare law: ``TubeModel`` without effects, or a law): the tip-loaded
  cantilever is statically determinate and stays in the x-z plane, so the equilibrium of the
  chain is the statics of its cuts, ``M(kappa_k) = F a_k`` at every joint ``k`` (lever arm
  ``a_k`` from joint ``k`` to the tip), a system of ``n`` equations in ``n`` unknowns
  (:mod:`fitting._bench.planar`, which derives it from the energy of
  ``jaxtube._mechanics`` and shows that it is the same discrete model, not an
  approximation). The wrinkling load fixes the root curvature at the law's wrinkling
  curvature and solves for ``F`` and the other joint rotations; the collapse load likewise;
  the tip deflection solves for the joint rotations at ``F_tip``. Each takes safeguarded
  Newton steps until its residual is at most ``planar_tolerance``, at most
  ``planar_*_steps`` of them (under ``vmap`` a chunk stops when its slowest point has
  converged; a point's result does not depend on its chunk). A point whose equilibrium
  residual is still above ``planar_tolerance`` is reported as not converged, and
  ``moment_mismatch`` is ``|F a_1 / M_target - 1|`` (above ``moment_tolerance``: not
  converged). The tests check
  this route against single solves of the generic 3-D solver ``jaxtube.equilibrium``.
- *Generic route* (a ``TubeModel`` with effects: reinforcement, self-weight, user effects;
  effects that need rig features, such as clamp compliance and shear, are refused as
  before): ``jaxtube.equilibrium`` of the 3-D chain with the effects applied by
  :meth:`fitting.CantileverRig.specimen_parameters`. The tip deflection is reached in
  ``tip_steps`` equal load steps from the unloaded shape (each step warm-started from the
  previous one); each load is found by the Newton iteration
  ``F_(k+1) = F_k + (M_target - M_root(F_k)) / M_root'(F_k)``, with the slope
  ``dM_root/dF`` of each equilibrium from the implicit function theorem (a ``jax.jvp``
  through the solve), starting from ``M_w / L`` on the unloaded shape (wrinkling) and
  continuing from the wrinkling equilibrium (collapse); each solve is warm-started from the
  previous one (the first collapse step uses ``F M_c / M_root``, a lower bound, since the
  wrinkling equilibrium sits at the law's kink). ``M_root(F)`` is increasing and concave on
  the stable branch, so the iterates approach from below, quadratically. The reported load
  is the one of the last solve (``wrinkling_iterations``, ``collapse_iterations`` solves),
  and ``moment_mismatch`` is ``|M_root / M_target - 1|`` there; above
  ``moment_tolerance`` the point is reported as not converged. 30-60 times slower than
  the planar route (``experiments/bench_sweep.py``), which also found a defect of the
  solver, since fixed: at some specimens this iteration returned its starting load
  ``M_w / L`` as the wrinkling load, because the first wrinkling solve's linear step put
  the root joint exactly on the tension-field law's onset, where the law's computed second
  derivative and with it the old stopping rule's ``|H z|`` scale exploded, so the solve
  stopped after one step. The law's Hessian is now exact there and the stopping rule's
  scale is the largest generalised force of a term (``tests/test_solver.py``,
  ``tests/test_convergence_honesty.py``).

**Failures are per point and never hidden.** Each quantity has a status code
(:data:`STATUS_MESSAGES`); a quantity that is not available is NaN in the arrays and blank
in the CSV, and its reason is given in words (:meth:`SweepResult.failure_reasons`). A law
without a wrinkled (or collapsed) regime in the bracket gives ``STATUS_NO_REGIME``, and a
root curvature that only a first segment turned past the vertical could carry (``kappa
l_1 >= pi / 2``, ``l_1 = L / (2 n)``; the planar route) gives ``STATUS_UNREACHABLE``: both
are "not applicable", not failures.

**Batching.** All points are one jitted function (the planar route's a ``vmap``, the generic
route's through ``jaxtube.each_member``: one after another on a CPU), evaluated in chunks of
``chunk_size`` points (bounded memory; a ``tqdm`` progress bar over the chunks). With more
than one device (``jax.devices()``: several GPUs, forced host devices, or the hosts of
``jax.distributed``), each chunk is split along the point axis over a one-dimensional
``jax.sharding.Mesh`` by ``jax.shard_map``, each device evaluating its own points (the
generic route's on a CPU one after another, :func:`_compiled_chunk` says why); the
chunk size is rounded up to a multiple of the device count and the grid padded by repeating
its last point (padding is dropped). Every point's computation is independent of the
others, so a sharded sweep equals the single-device sweep (tests check this on 4 forced
host devices for the planar route and on 2 for the generic one).
"""

from __future__ import annotations

import functools
import math
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental import multihost_utils
from jax.sharding import Mesh, NamedSharding, PartitionSpec

import jaxtube as jt

from .._bench.planar import deflection_at_load, load_at_root_curvature
from .._bench.rig import DOWN, CantileverRig, TubeModel
from .result import SweepResult, SweepSettings
from .status import (
    STATUS_MOMENT_MISSED,
    STATUS_NO_REGIME,
    STATUS_OK,
    STATUS_SOLVER_FAILED,
    STATUS_UNREACHABLE,
)

#: Bracket of the bisection for the regime boundaries [1/m], and its halvings.
CURVATURE_BRACKET = (1e-9, 1e6)
_BISECTIONS = 64

def regime_boundaries(law: jt.AbstractMomentLaw, pressure, radius):
    """Curvatures [1/m] where ``law.regime`` first reaches 1 and 2, by bisection in
    ``log kappa`` over :data:`CURVATURE_BRACKET` (regimes are non-decreasing in
    ``|kappa|``); NaN where the regime is not reached in the bracket. Scalars in, scalars
    out (vmap for batches)."""
    lo, hi = (math.log(k) for k in CURVATURE_BRACKET)

    def boundary(level):
        def halve(_, bracket):
            a, b = bracket
            mid = 0.5 * (a + b)
            above = law.regime(jnp.exp(mid), pressure, radius) >= level
            return jnp.where(above, a, mid), jnp.where(above, mid, b)

        start = (jnp.asarray(lo), jnp.asarray(hi))
        _, upper = jax.lax.fori_loop(0, _BISECTIONS, halve, start)
        reached = law.regime(jnp.exp(jnp.asarray(hi)), pressure, radius) >= level
        return jnp.where(reached, jnp.exp(upper), jnp.nan)

    return boundary(1), boundary(2)


@functools.lru_cache(maxsize=8)
def _solution_template(rig: CantileverRig):
    """Shapes of one cantilever Solution (an abstract evaluation; nothing is compiled)."""
    structure, params = rig.template()
    return jax.eval_shape(lambda p: jt.equilibrium(structure, p, solver=rig.solver), params)


def _thresholds(law: jt.AbstractMomentLaw, pressure, radius):
    """``EI0`` [N m^2], the wrinkling and collapse curvatures [1/m] and moments [N m] of the
    law at one specimen, and whether each regime exists (the collapse only after a
    wrinkling); shared by both routes."""
    kappa_w, kappa_c = regime_boundaries(law, pressure, radius)
    moment_w = law.moment(kappa_w, pressure, radius)
    moment_c = law.moment(kappa_c, pressure, radius)
    w_defined = jnp.isfinite(moment_w)
    return (law.initial_stiffness(pressure, radius), kappa_w, kappa_c, moment_w, moment_c,
            w_defined, jnp.isfinite(moment_c) & w_defined)


def _planar_point(law: jt.AbstractMomentLaw, settings: SweepSettings, pressure, radius,
                  length, tip_load):
    """All quantities of one specimen by the planar route (scalars in; traced under
    ``vmap``): three solves of :mod:`fitting._bench.planar`."""
    stiffness, kappa_w, kappa_c, moment_w, moment_c, w_defined, c_defined = _thresholds(
        law, pressure, radius)
    n, tolerance = settings.segments, settings.planar_tolerance

    def load_at(curvature, defined, steps):
        # An undefined regime still runs (lockstep) on a harmless curvature; its status
        # says not applicable and its value is dropped.
        safe = jnp.where(defined, curvature, 1e-6 / length)
        solved = load_at_root_curvature(law, pressure, radius, length, safe, n, steps,
                                        tolerance)
        status = jnp.select(
            [~defined, ~solved.reachable, solved.result != 0,
             ~(solved.root_mismatch <= settings.moment_tolerance)],
            [STATUS_NO_REGIME, STATUS_UNREACHABLE, STATUS_SOLVER_FAILED,
             STATUS_MOMENT_MISSED], STATUS_OK)
        return (jnp.where(status == STATUS_OK, solved.load, jnp.nan), status,
                jnp.where(defined, solved.result, 0),
                jnp.where(defined, solved.root_mismatch, jnp.nan),
                jnp.where(defined, solved.steps, 0))

    f_w, s_w, r_w, m_w, i_w = load_at(kappa_w, w_defined, settings.planar_wrinkling_steps)
    f_c, s_c, r_c, m_c, i_c = load_at(kappa_c, c_defined, settings.planar_collapse_steps)
    tip = deflection_at_load(law, pressure, radius, length, tip_load, n,
                             settings.planar_deflection_steps, tolerance)
    s_t = jnp.where(tip.result == 0, STATUS_OK, STATUS_SOLVER_FAILED)
    return dict(initial_stiffness=stiffness, wrinkling_moment=moment_w,
                collapse_moment=moment_c, wrinkling_load=f_w, collapse_load=f_c,
                tip_deflection=jnp.where(s_t == STATUS_OK, tip.tip_deflection, jnp.nan),
                wrinkling_status=s_w, collapse_status=s_c, deflection_status=s_t,
                wrinkling_solver_result=r_w, collapse_solver_result=r_c,
                deflection_solver_result=tip.result, wrinkling_mismatch=m_w,
                collapse_mismatch=m_c, iterations=i_w + i_c + tip.steps)


def _generic_point(model: TubeModel, settings: SweepSettings, pressure, radius, length,
                   tip_load):
    """All quantities of one specimen by the generic route (scalars in; traced under
    ``vmap``): one ``lax.scan`` over the equilibrium solves of the module docstring."""
    rig = CantileverRig(segments=settings.segments, solver=settings.solver)
    structure, _ = rig.template()
    tip = structure.node_id("tube:end")
    params = rig.specimen_parameters(model, pressure, radius, length)
    params = eqx.tree_at(lambda p: p.node_force, params,
                         params.node_force.at[tip].set(jnp.asarray(DOWN)))  # 1 N down
    stiffness, kappa_w, kappa_c, moment_w, moment_c, w_defined, c_defined = _thresholds(
        model.bending_law, pressure, radius)

    # The unloaded shape as a Solution to start from (equilibrium reads state, multipliers).
    start = jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), _solution_template(rig))
    start = eqx.tree_at(lambda s: s.state, start, jt.initial_state(structure, params))

    # One scan over every solve: phase 0 the tip-load steps, 1 wrinkling, 2 collapse.
    n_t, n_w, n_c = settings.tip_steps, settings.wrinkling_iterations, settings.collapse_iterations
    phase = np.repeat([0, 1, 2], [n_t, n_w, n_c])
    first = np.concatenate([[True] + [False] * (n_t - 1), [True] + [False] * (n_w - 1),
                            [True] + [False] * (n_c - 1)])
    fraction = np.concatenate([np.arange(1, n_t + 1) / n_t, np.zeros(n_w + n_c)])

    def solve(load, initial):
        sol = jt.equilibrium(structure, jt.scale_loads(params, load), initial=initial,
                             solver=settings.solver)
        return sol, jnp.linalg.norm(sol.joint_moment[0, :2])

    def step(carry, xs):
        previous, load, moment, slope = carry
        phase_k, first_k, fraction_k = xs
        target = jnp.where(phase_k == 2, moment_c, moment_w)
        # M_root(F) = F l(F) with a lever arm l that shortens as F grows, so the ratio
        # update F M_target / M_root(F) never passes the answer (it is a lower bound).
        # Newton with the slope dM_root/dF of the previous solve (implicit function theorem)
        # converges quadratically and, M_root being concave on the stable branch, also stays
        # below; it is used where it is finite and above the ratio update. The first
        # collapse step takes the ratio update: the wrinkling solve sits exactly at the
        # law's kink, where the slope is one-sided.
        ratio = load * target / moment
        newton = load + (target - moment) / slope
        newton_ok = jnp.isfinite(newton) & (slope > 0) & (newton > ratio) & ~first_k
        iterated = jnp.where(newton_ok, newton, ratio)
        load_new = jnp.select(
            [phase_k == 0, (phase_k == 1) & first_k],
            [tip_load * fraction_k, moment_w / length], iterated)
        defined = jnp.where(phase_k == 0, True, jnp.where(phase_k == 1, w_defined, c_defined))
        load_new = jnp.where(defined, load_new, 0.0)
        restart = first_k & (phase_k < 2)
        initial = jax.tree.map(lambda a, b: jnp.where(restart, a, b), start, previous)
        (sol, root_moment), (_, slope_new) = jax.jvp(
            lambda f: solve(f, initial), (load_new,), (jnp.ones_like(load_new),))
        deflection = jnp.dot(sol.node_position[tip] - params.node_position[tip], DOWN)
        out = (load_new, root_moment, deflection, sol.converged, sol.result, sol.iterations)
        return (sol, load_new, root_moment, slope_new), out

    carry0 = (start, jnp.zeros(()), jnp.ones(()), jnp.ones(()))
    _, (loads, moments, deflections, converged, results, iterations) = jax.lax.scan(
        step, carry0, (phase, first, fraction))

    def summary(k_phase, target, defined):
        chosen = phase == k_phase
        ok = jnp.all(jnp.where(chosen, converged, True))
        worst = jnp.max(jnp.where(chosen, results, 0))
        last = np.flatnonzero(chosen)[-1]
        mismatch = jnp.abs(moments[last] / target - 1.0)
        status = jnp.where(~defined, STATUS_NO_REGIME,
                           jnp.where(~ok, STATUS_SOLVER_FAILED,
                                     jnp.where(mismatch <= settings.moment_tolerance,
                                               STATUS_OK, STATUS_MOMENT_MISSED)))
        value = jnp.where(status == STATUS_OK, loads[last], jnp.nan)
        return value, status, worst, jnp.where(defined, mismatch, jnp.nan)

    f_w, s_w, r_w, m_w = summary(1, moment_w, w_defined)
    f_c, s_c, r_c, m_c = summary(2, moment_c, c_defined)
    t_ok = jnp.all(jnp.where(phase == 0, converged, True))
    s_t = jnp.where(t_ok, STATUS_OK, STATUS_SOLVER_FAILED)
    v = jnp.where(t_ok, deflections[n_t - 1], jnp.nan)
    r_t = jnp.max(jnp.where(phase == 0, results, 0))
    return dict(initial_stiffness=stiffness, wrinkling_moment=moment_w,
                collapse_moment=moment_c, wrinkling_load=f_w, collapse_load=f_c,
                tip_deflection=v, wrinkling_status=s_w, collapse_status=s_c,
                deflection_status=s_t, wrinkling_solver_result=r_w,
                collapse_solver_result=r_c, deflection_solver_result=r_t,
                wrinkling_mismatch=m_w, collapse_mismatch=m_c,
                iterations=jnp.sum(iterations))


@functools.lru_cache(maxsize=8)
def _compiled_chunk(settings: SweepSettings, devices: tuple, route: str = "planar"):
    """One jitted program over a chunk of points, split over ``devices`` along the points.

    Its first argument is the law (planar route) or the :class:`TubeModel` (generic). The
    planar route's points are one ``vmap`` (closed-form statics, which a ``vmap``
    vectorises); the generic route's go through ``jaxtube.each_member``: one after another
    on a CPU (a ``vmap`` of those solves does not pay there, and a ``vmap`` per device
    deadlocked jaxlib 0.10.2's batched LU: a 20-segment generic sweep on 2 forced host
    devices of a 2-core machine hung for good, 2026-12-05; ``jaxtube._members``), one
    ``vmap`` elsewhere. On several devices ``jax.shard_map`` gives each its own points, with
    no communication (a device's while-loops run to its own points' convergence)."""
    point = {"planar": _planar_point, "generic": _generic_point}[route]

    def chunk(model, pressure, radius, length, tip_load):
        one = functools.partial(point, model, settings)
        if route == "generic":
            return jt.each_member(one, pressure, radius, length, tip_load,
                                  sequential=devices[0].platform == "cpu")
        return jax.vmap(one)(pressure, radius, length, tip_load)

    if len(devices) == 1:
        return jax.jit(chunk), None
    mesh = Mesh(np.asarray(devices), ("points",))
    points = NamedSharding(mesh, PartitionSpec("points"))
    replicated = NamedSharding(mesh, PartitionSpec())
    split = jax.shard_map(chunk, mesh=mesh, in_specs=(PartitionSpec(),) + (
        PartitionSpec("points"),) * 4, out_specs=PartitionSpec("points"), check_vma=False)
    return jax.jit(split, in_shardings=(replicated, points, points, points, points),
                   out_shardings=points), points


def _to_devices(values: np.ndarray, sharding):
    if sharding is None:
        return jnp.asarray(values)
    # Works across the processes of jax.distributed too: every process holds the whole grid
    # and supplies the shards of its own devices.
    return jax.make_array_from_callback(values.shape, sharding, lambda index: values[index])


def _to_host(values) -> np.ndarray:
    if jax.process_count() > 1:
        return np.asarray(multihost_utils.process_allgather(values, tiled=True))
    return np.asarray(values)


def checked_specimens(pressure, radius, length, tip_load) -> list[np.ndarray]:
    """The specimens broadcast to one shape (float arrays), or ``ValueError`` naming the
    first that is not finite, not positive (pressure, radius, length) or negative (tip
    load), or that there are no points."""
    arrays = np.broadcast_arrays(*(np.asarray(v, float) for v in
                                   (pressure, radius, length, tip_load)))
    for name, values, lowest in zip(("pressure", "radius", "length", "tip_load"), arrays,
                                    (0, 0, 0, None)):
        if not np.all(np.isfinite(values)):
            raise ValueError(f"sweep: {name} must be finite")
        if lowest is not None and not np.all(values > lowest):
            raise ValueError(f"sweep: {name} must be positive, found {values.min():g}")
    if np.any(arrays[3] < 0):
        raise ValueError("sweep: tip_load must be >= 0 (it acts downwards)")
    if arrays[0].size == 0:
        raise ValueError("sweep: no points")
    return arrays


def sweep(law: jt.AbstractMomentLaw | TubeModel, pressure, radius, length, tip_load,
          settings: SweepSettings = SweepSettings(), devices=None,
          progress: bool = False) -> SweepResult:
    """Evaluate a bending law on the standard cantilever at every specimen.

    Arguments (any mutually broadcastable shapes; ``np.meshgrid`` makes a grid):
        law: a bending law (:class:`jaxtube.AbstractMomentLaw`, e.g. from
            :func:`fitting.load_law`) or a :class:`fitting.TubeModel`; a law, or a model
            without effects, takes the planar route, a model with effects the generic one
            (module docstring; its torsion law plays no part: the cantilever does not
            twist).
        pressure: overpressure [Pa] (> 0); radius [m] (> 0); length [m] (> 0);
        tip_load: the dead tip load of the tip deflection [N] (>= 0).
        settings: :class:`SweepSettings`; devices: devices to shard over (default: all of
            ``jax.devices()``); progress: a ``tqdm`` bar over the chunks.

    Returns a :class:`SweepResult` of the broadcast shape (quantities defined in the module
    docstring). Raises ``ValueError`` for non-positive or non-finite specimens.
    """
    model = law if isinstance(law, TubeModel) else TubeModel(bending_law=law)
    arrays = checked_specimens(pressure, radius, length, tip_load)
    shape = arrays[0].shape
    devices = tuple(jax.devices() if devices is None else devices)
    count = int(np.prod(shape))
    size = -(-min(settings.chunk_size, count) // len(devices)) * len(devices)
    padded = -(-count // size) * size
    flat = [np.concatenate([a.reshape(-1), np.repeat(a.reshape(-1)[-1:], padded - count)])
            for a in arrays]
    route = "generic" if model.effects else "planar"
    compiled, sharding = _compiled_chunk(settings, devices, route)
    argument = model if route == "generic" else model.bending_law
    started = time.perf_counter()
    pieces = []
    chunks = range(0, padded, size)
    if progress:
        from tqdm.auto import tqdm  # lazy: only a sweep that shows progress needs it

        chunks = tqdm(chunks, desc=f"sweep ({count} points, {len(devices)} device(s))",
                      unit="chunk")
    for start in chunks:
        inputs = [_to_devices(a[start:start + size], sharding) for a in flat]
        out = compiled(argument, *inputs)
        pieces.append({key: _to_host(value) for key, value in out.items()})
    seconds = time.perf_counter() - started
    fields = {key: np.concatenate([p[key] for p in pieces])[:count].reshape(shape)
              for key in pieces[0]}
    return SweepResult(pressure=arrays[0].copy(), radius=arrays[1].copy(),
                       length=arrays[2].copy(), tip_load=arrays[3].copy(), **fields,
                       settings=settings, devices=len(devices), seconds=seconds,
                       route=route)
