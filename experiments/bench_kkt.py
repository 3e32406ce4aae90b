"""KKT benchmark: one Newton step and one KKT solve, sparse (KLU) against dense, same run.

The problem: a tree of tubes with loop constraints, about the size of a whole kite: two
straight 50-segment booms 1 m apart, clamped at one end of the first, joined by 7 rungs of
21 segments; each rung is rigidly joined to the first boom (tree edge) and pinned to the
second (a loop closure, 3 constraints), and the far end of the second boom is joined to the
first by a short pinned tie. 253 segments: n = 762 unknowns (3 per segment and the root
position), m = 27 constraints (clamp 3 + 8 closures x 3). A load on every rung.

Measured, each route compiled separately with ``NewtonKKT(linear_solver=...)``:

- *one Newton step*: ``jaxtube.equilibrium`` with ``max_steps=1`` (the linearisation, the
  Hessian blocks, one KKT solve plus any regularised retries, the line search), on the
  dense, sparse and augmented routes (``auto`` takes the augmented one here);
- *one KKT solve*: the KKT matrix at the unloaded state with ``mu = 0``, solved once
  (dense: ``jnp.linalg.solve``; sparse: KLU with the symbolic analysis kept);
- the size crossover of ``linear_solver="auto"``: one 10-step displacement-controlled
  cantilever curve with 10, 20, 40 and 80 segments, dense against sparse.

Target: the sparse Newton step at least 10x faster than the dense one. Run from the
repository root::

    python experiments/bench_kkt.py [--quick]

Writes ``experiments/results/bench_kkt.txt`` (``--out``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
try:
    import jaxtube as jt
except ModuleNotFoundError:  # run from a checkout without installing the package
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import jaxtube as jt

import jax
import jax.numpy as jnp
from bench_solver import Report, load_text, time_warm
from jax.flatten_util import ravel_pytree

from jaxtube._mechanics import reference_geometry
from jaxtube._solver.kkt_linear import DenseKKT, SparseKKT

BOOM_SEGMENTS = 50
RUNGS = 7
RUNG_SEGMENTS = 21
TARGET = 10.0


def ladder():
    law = jt.SplineLaw.from_tension_field(150e3, 2.5e4, 0.06)
    torsion = jt.LinearLaw(150.0)
    tubes = [jt.straight_tube(name, (0, y, 0), (5.0, y, 0), BOOM_SEGMENTS, 0.06, 2.5e4, law,
                              torsion_law=torsion) for name, y in (("a", 0.0), ("b", 1.0))]
    connections, forces = [], {}
    for r in range(RUNGS):
        k = 5 + 6 * r
        x = 5.0 * k / BOOM_SEGMENTS
        tubes.append(jt.straight_tube(f"r{r}", (x, 0, 0), (x, 1.0, 0), RUNG_SEGMENTS, 0.04,
                                      3e4, law, torsion_law=torsion))
        connections += [jt.Connection(f"a:{k}", f"r{r}:0", "rigid"),
                        jt.Connection(f"b:{k}", f"r{r}:end", "pinned")]
        forces[f"r{r}:{RUNG_SEGMENTS // 2}"] = [0.0, 0.0, -5.0]
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
    report(f"jaxtube KKT benchmark; {load_text()}")
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

    steps = {}
    for label in ("dense", "sparse", "augmented"):
        solver = jt.NewtonKKT(max_steps=1, linear_solver=label)
        fn = jax.jit(lambda p, solver=solver: jt.equilibrium(structure, p, solver=solver))
        started = time.perf_counter()
        compiled = fn.lower(params).compile()
        compile_s = time.perf_counter() - started
        timing, sol = time_warm(compiled, params, repeats=repeats)
        steps[label] = (timing, np.asarray(sol.node_position))
        report(f"one Newton step ({label}): compile {compile_s:.1f} s; warm "
               f"{timing.text(1e-3, 'ms')}; result code {int(sol.result)}")
    for label in ("sparse", "augmented"):
        ratio = steps["dense"][0].median / steps[label][0].median
        agree = np.max(np.abs(steps["dense"][1] - steps[label][1]))
        report(f"  {label}: positions after the step agree with dense to {agree:.1e} m; "
               f"ratio dense / {label} {ratio:.1f}x")
        verdict = "met" if ratio >= TARGET else f"missed ({ratio:.1f}x)"
        report(f"target: {label} Newton step >= {TARGET:g}x faster than dense: {verdict}")

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
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent
                        / "results" / "bench_kkt.txt")
    args = parser.parse_args(argv)
    report = Report()
    run(report, repeats=2 if args.quick else 5)
    report.write(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
