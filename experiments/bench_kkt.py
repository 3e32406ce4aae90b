"""KKT benchmark: one Newton step and one KKT solve, sparse (KLU) against dense, same run.

The problem: a tree of tubes with loop constraints, about the size of a whole kite: two
straight 50-segment booms 1 m apart, clamped at one end of the first, joined by 7 rungs of
21 segments; each rung is rigidly joined to the first boom (tree edge) and pinned to the
second (a loop closure, 3 constraints), and the far end of the second boom is joined to the
first by a short tie of 3 segments, rigid at the first and pinned at the second. 250
segments: n = 753 unknowns (3 per segment and the root position), m = 24 constraints
(clamp 3 + 7 closures x 3). A load on every rung.

Measured, each route compiled separately with ``NewtonKKT(linear_solver=...)``:

- *one Newton step*: ``jaxtube.equilibrium`` with ``max_steps=1`` (the linearisation, the
  Hessian blocks, one KKT solve plus any regularised retries, the line search), on the
  dense, sparse and augmented routes (``auto`` takes the augmented one here); also with
  ``max_steps=0`` (the start and the post-processing of the result, no Newton pass), so
  that the step proper is the difference;
- *the ceiling of the ratio*: the work every route does in a step whatever its linear
  algebra (each energy term's gradient, ``J^T lambda``, the Hessian blocks, the full step's
  trial gradient), timed as one program: even a KKT solve that cost nothing leaves the
  sparse step this long, so the dense step over it bounds the ratio any linear solver can
  reach;
- *one KKT solve*: the KKT matrix at the unloaded state with ``mu = 0``, solved once
  (dense: ``jnp.linalg.solve``; sparse: KLU with the symbolic analysis kept);
- the size crossover of ``linear_solver="auto"``: one KKT solve on cantilevers of 5 to 160
  segments, dense against sparse;
- with ``--scaling``: the Newton step, dense against augmented, on the ladder at half and
  twice its segment counts (123 and 497 segments), to show how the ratio grows with size.

Target: the sparse Newton step at least 10x faster than the dense one. Run from the
repository root::

    python -m experiments.bench_kkt [--quick] [--scaling]

Writes ``experiments/results/bench_kkt.txt`` (``--out``).
"""

from __future__ import annotations

import argparse
import datetime
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

import jaxtube as jt
from experiments.bench_solver import Report, load_text, time_warm
from jaxtube._mechanics import reference_geometry
from jaxtube._solver.kkt_linear import DenseKKT, SparseKKT

BOOM_SEGMENTS = 50
RUNGS = 7
RUNG_SEGMENTS = 21
TARGET = 10.0


def ladder(scale: float = 1.0):
    """The ladder tree; ``scale`` multiplies the segment counts of booms and rungs (1: 250
    segments, 753 unknowns; 2: 497 segments, 1,494 unknowns)."""
    booms, rung_segments = round(BOOM_SEGMENTS * scale), round(RUNG_SEGMENTS * scale)
    law = jt.SplineLaw.from_tension_field(150e3, 2.5e4, 0.06)
    torsion = jt.LinearLaw(150.0)
    tubes = [jt.straight_tube(name, (0, y, 0), (5.0, y, 0), booms, 0.06, 2.5e4, law,
                              torsion_law=torsion) for name, y in (("a", 0.0), ("b", 1.0))]
    connections, forces = [], {}
    for r in range(RUNGS):
        k = round((5 + 6 * r) * scale)
        x = 5.0 * k / booms
        tubes.append(jt.straight_tube(f"r{r}", (x, 0, 0), (x, 1.0, 0), rung_segments, 0.04,
                                      3e4, law, torsion_law=torsion))
        connections += [jt.Connection(f"a:{k}", f"r{r}:0", "rigid"),
                        jt.Connection(f"b:{k}", f"r{r}:end", "pinned")]
        forces[f"r{r}:{rung_segments // 2}"] = [0.0, 0.0, -5.0]
    tubes.append(jt.straight_tube("tie", (5.0, 0, 0), (5.0, 1.0, 0), 3, 0.03, 3e4, law,
                                  torsion_law=torsion))
    connections += [jt.Connection("a:end", "tie:0", "rigid"),
                    jt.Connection("b:end", "tie:end", "pinned")]
    return jt.build_structure(tubes, [jt.Support("a:0", "clamped")], connections,
                              node_force=forces)


def kkt_parts(structure, params):
    """Hessian blocks and constraint Jacobian at the unloaded state (the solver's pieces),
    computed in one compiled program (the block positions are static numpy arrays, kept
    from the trace)."""
    from jaxtube._mechanics import energy_terms_and_constraints as _objective_terms
    from jaxtube._mechanics import lagrangian_hessian_blocks

    positions = []

    @jax.jit
    def parts(params):
        geometry = reference_geometry(structure, params)
        state = jt.initial_state(structure, params)
        z, unravel = ravel_pytree(state)
        jacobian = jax.jacrev(lambda zz: _objective_terms(structure, geometry, unravel(zz),
                                                          params, None)[1])(z)
        lam = jnp.ones((jacobian.shape[0],))
        blocks = lagrangian_hessian_blocks(structure, geometry, params, None, state, lam)
        positions[:] = [(r, c) for r, c, _ in blocks]
        return [v for _, _, v in blocks], jacobian

    values, jacobian = parts(params)
    return [(r, c, v) for (r, c), v in zip(positions, values)], jacobian


def kkt_solvers(blocks, n, m):
    """One KKT solve from block values, Jacobian and right-hand side, by each route."""
    dense, sparse = DenseKKT(n, m), SparseKKT(blocks, n, m)

    def rebuilt(values):
        return [(r, c, v) for (r, c, _), v in zip(blocks, values)]

    def dense_solve(values, jacobian, rhs):
        hessian = dense.hessian(rebuilt(values))
        return dense.solve(dense.kkt(hessian, jacobian, 0.0, 0.0), rhs)

    def sparse_solve(values, jacobian, rhs):
        return sparse.solve(sparse.kkt(sparse.hessian(rebuilt(values)), jacobian, 0.0, 0.0),
                            rhs)

    return {"dense": dense_solve, "sparse": sparse_solve}


def newton_step_timings(report, structure, params, labels, repeats):
    """One Newton step by each route (``jaxtube.equilibrium`` with ``max_steps=1``) and the
    same call with no Newton pass (``max_steps=0``): ``({label: (Timing, node positions
    [N, 3] after the step)}, {label: median seconds with no pass})``."""
    steps, bare = {}, {}
    for label in labels:
        for max_steps in (1, 0):
            solver = jt.NewtonKKT(max_steps=max_steps, linear_solver=label)
            fn = jax.jit(lambda p, solver=solver: jt.equilibrium(structure, p, solver=solver))
            started = time.perf_counter()
            compiled = fn.lower(params).compile()
            compile_s = time.perf_counter() - started
            timing, sol = time_warm(compiled, params, repeats=10 * repeats)
            if max_steps:
                steps[label] = (timing, np.asarray(sol.node_position))
                report(f"one Newton step ({label}): compile {compile_s:.1f} s; warm "
                       f"{timing.text(1e-3, 'ms')}; result code {int(sol.result)}")
            else:
                bare[label] = timing.median
                report(f"  the same call with no Newton pass (start, post-processing): "
                       f"{timing.text(1e-3, 'ms')}")
    return steps, bare


def scaling(report: Report, repeats: int) -> None:
    """The Newton step, dense against augmented, on the ladder at half, once and twice its
    size: how the ratio grows with the structure."""
    report("scaling: one Newton step on the ladder at 0.5, 1 and 2 times its segment counts")
    for scale in (0.5, 1.0, 2.0):
        structure, params = ladder(scale)
        n = ravel_pytree(jt.initial_state(structure, params))[0].size
        report(f"- scale {scale:g}: {structure.segment_count} segments, n = {n} unknowns")
        steps, bare = newton_step_timings(report, structure, params, ("dense", "augmented"),
                                          repeats)
        dense, augmented = steps["dense"][0].median, steps["augmented"][0].median
        report(f"  dense / augmented: {dense / augmented:.1f}x (the step proper: "
               f"{(dense - bare['dense']) / (augmented - bare['augmented']):.1f}x); positions "
               f"agree to "
               f"{np.max(np.abs(steps['dense'][1] - steps['augmented'][1])):.1e} m")


def shared_step_work(structure, params, repeats):
    """Timing of the work in one Newton step that every KKT route does, as one program: the
    gradient of each energy term, ``J^T lambda`` (one reverse pass of the constraints), the
    Hessian blocks and the gradient of the Lagrangian at the full step (the line search's
    first trial), at the unloaded state with unit multipliers."""
    from jaxtube._equilibrium import _model_hessian, _model_objective

    args = (params, reference_geometry(structure, params), None)
    state = jt.initial_state(structure, params)
    z, unravel = ravel_pytree(state)

    def objective(zz):
        return _model_objective(unravel(zz), args, structure=structure, control_node=None)

    k, m = (x.shape[0] for x in jax.eval_shape(objective, z))

    @jax.jit
    def work(z, lam, dz):
        parts, part_pullback = jax.vjp(lambda zz: objective(zz)[0], z)
        (part_grads,) = jax.vmap(part_pullback)(jnp.eye(k))
        c, constraint_pullback = jax.vjp(lambda zz: objective(zz)[1], z)
        (jt_lam,) = constraint_pullback(lam)
        blocks = _model_hessian(unravel(z), lam, args, structure=structure,
                                control_node=None)
        trial = jax.grad(lambda zz: jnp.sum(objective(zz)[0]) + lam @ objective(zz)[1])(z + dz)
        return parts, part_grads, c, jt_lam, [v for _, _, v in blocks], trial

    lam, dz = jnp.ones((m,)), 1e-3 * jnp.ones_like(z)
    timing, _ = time_warm(work, z, lam, dz, repeats=10 * repeats)
    return timing


def solve_timings(structure, params, repeats):
    """Median seconds of one KKT solve by each route at the unloaded state."""
    blocks, jacobian = kkt_parts(structure, params)
    m, n = jacobian.shape
    rhs = jnp.asarray(np.random.default_rng(0).standard_normal(n + m))
    values = [v for _, _, v in blocks]
    medians = {}
    for label, fn in kkt_solvers(blocks, n, m).items():
        compiled = jax.jit(fn).lower(values, jacobian, rhs).compile()
        timing, _ = time_warm(compiled, values, jacobian, rhs, repeats=10 * repeats)
        medians[label] = timing.median
    return medians


def run(report: Report, repeats: int) -> None:
    report(f"jaxtube KKT benchmark, {datetime.datetime.now().isoformat(timespec='seconds')}, "
           f"{repeats} repeats (x 5 for the solves, x 10 for the steps); {load_text()}")
    structure, params = ladder()
    blocks, jacobian = kkt_parts(structure, params)
    m, n = jacobian.shape
    report(f"ladder tree: {structure.segment_count} segments, n = {n} unknowns, m = {m} "
           f"constraints ({len(structure.closures)} loop closures)")
    rhs = jnp.asarray(np.random.default_rng(0).standard_normal(n + m))
    sparse = SparseKKT(blocks, n, m)
    report(f"KKT pattern: {sparse.nnz} nonzeros of {(n + m) ** 2} "
           f"({sparse.nnz / (n + m) ** 2:.2%})")
    values = [v for _, _, v in blocks]

    solves = {}
    for label, fn in kkt_solvers(blocks, n, m).items():
        compiled = jax.jit(fn).lower(values, jacobian, rhs).compile()
        timing, x = time_warm(compiled, values, jacobian, rhs, repeats=5 * repeats)
        solves[label] = (timing, np.asarray(x))
        report(f"one KKT solve ({label}, assembly from blocks included): "
               f"{timing.text(1e-3, 'ms')}")
    difference = np.max(np.abs(solves["dense"][1] - solves["sparse"][1]))
    report(f"  solutions agree to {difference / np.max(np.abs(solves['dense'][1])):.1e} "
           f"(relative); ratio dense / sparse "
           f"{solves['dense'][0].median / solves['sparse'][0].median:.1f}x")

    steps, bare = newton_step_timings(report, structure, params,
                                      ("dense", "sparse", "augmented"), repeats)
    for label in ("sparse", "augmented"):
        ratio = steps["dense"][0].median / steps[label][0].median
        proper = ((steps["dense"][0].median - bare["dense"])
                  / (steps[label][0].median - bare[label]))
        agree = np.max(np.abs(steps["dense"][1] - steps[label][1]))
        report(f"  {label}: positions after the step agree with dense to {agree:.1e} m; "
               f"ratio dense / {label} {ratio:.1f}x (the step proper, without the start and "
               f"post-processing: {proper:.1f}x)")
        verdict = "met" if ratio >= TARGET else f"missed ({ratio:.1f}x)"
        report(f"target: {label} Newton step >= {TARGET:g}x faster than dense: {verdict}")
    shared = shared_step_work(structure, params, repeats)
    dense_proper = steps["dense"][0].median - bare["dense"]
    report(f"the work of a step that no linear solver removes (each term's gradient, J^T "
           f"lambda, the Hessian blocks, the trial gradient; one program): "
           f"{shared.text(1e-3, 'ms')}")
    report(f"  ceiling: with a KKT solve that cost nothing, the dense step proper "
           f"({1e3 * dense_proper:.2f} ms) over this: {dense_proper / shared.median:.1f}x; the "
           f"whole call ({1e3 * steps['dense'][0].median:.2f} ms) over this plus the start and "
           f"post-processing: "
           f"{steps['dense'][0].median / (shared.median + bare['augmented']):.1f}x")

    report("crossover: one KKT solve (assembly from blocks included) on cantilevers:")
    law = jt.SplineLaw.from_tension_field(150e3, 2e4, 0.075)
    for segments in (5, 10, 20, 40, 80, 160):
        structure, params = jt.cantilever(1.0, 0.075, 2e4, segments, law, jt.LinearLaw(150.0))
        medians = solve_timings(structure, params, repeats)
        blocks, jacobian = kkt_parts(structure, params)
        size = sum(jacobian.shape)
        report(f"  {segments} segments (n + m = {size}): dense {1e3 * medians['dense']:.3f} ms, "
               f"sparse {1e3 * medians['sparse']:.3f} ms, dense / sparse "
               f"{medians['dense'] / medians['sparse']:.2f}x")
    report(f"(auto takes the sparse route from n + m >= {jt_crossover()})")


def jt_crossover():
    from jaxtube._solver.kkt_linear import SPARSE_CROSSOVER

    return SPARSE_CROSSOVER


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 repeats instead of 5")
    parser.add_argument("--scaling", action="store_true",
                        help="also the Newton step at half and twice the ladder's size")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent
                        / "results" / "bench_kkt.txt")
    args = parser.parse_args(argv)
    report = Report()
    run(report, repeats=2 if args.quick else 5)
    if args.scaling:
        scaling(report, repeats=2 if args.quick else 5)
    report.write(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
