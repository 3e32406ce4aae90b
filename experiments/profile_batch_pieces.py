"""Where a batched Newton pass spends its time (issue 13's vmap target): per-member cost of
each piece of one linearisation under ``jax.vmap``, batch 1 against 64 and 256, on the
curve of ``bench_solver.py`` (20-segment 3-D cantilever, 63 unknowns, 4 constraints) at a
state on its path (step 25 of 50, in the wrinkled regime).

Pieces: the energy terms; the energy's gradient; the rows the stopping rule needs (each
energy term's gradient and the constraint Jacobian, as ``jaxtube._solver.newton_kkt``
computes them); the Hessian blocks of the Lagrangian (``lagrangian_hessian_blocks``); a
dense 67 x 67 KKT solve. Then the largest piece taken apart: the joint blocks of the
Hessian as ``jax.hessian`` of the joint energy (the engine's route until 2026-12-05; it
now takes the forward-mode Jacobian of the closed-form gradient, inside "Hessian blocks"),
the law's part alone, the joint rotation's part alone (``log(exp(-u) exp(v))``
differentiated twice), by rotation matrices and, as a what-if not used by the engine, by
unit quaternions (defined here; equal to the matrix route to round-off below a relative
angle of pi).

Each piece is its own jitted program called from Python, so at batch 1 the figures include
the dispatch of one call (tens of microseconds) that a solve inside its while loop does not
pay; compare batches with each other, not with the solver's per-step times.

Last, the whole of one Newton pass of the engine, measured as the difference of two
``jt.equilibrium`` calls (``max_steps=1`` less ``max_steps=0``), so without the dispatch: at
batch 1 it is what a loop of single solves pays per pass, and its ratio to the batched
figure is the most a batch can gain over that loop per pass (before lockstep and the line
search's extra trials, which only lower it).

    python -m experiments.profile_batch_pieces [--out experiments/results/profile_batch_pieces.txt]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

import jaxtube as jt
from experiments import bench_solver
from jaxtube._equilibrium import _model_hessian, _model_objective, tube_reference_geometry
from jaxtube._mechanics.kinematics import relative_joint_rotation

BATCHES = (1, 64, 256)
SMALL = 1e-4  # the engine's Taylor threshold on t^2


def median_seconds(fn, *args, repeats=30) -> float:
    jax.block_until_ready(fn(*args))
    walls = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn(*args))
        walls.append(time.perf_counter() - start)
    return float(np.median(walls))


def quaternion_relative_rotation(u, v):
    """What-if: ``log(exp(-u) exp(v))`` by unit quaternions, Taylor branches in ``t^2``."""
    def half_angle(x):
        small = x < SMALL
        t = jnp.sqrt(jnp.where(small, 1.0, x))
        c = jnp.where(small, 1.0 - x / 8.0 + x * x / 384.0 - x**3 / 46080.0, jnp.cos(0.5 * t))
        s = jnp.where(small, 0.5 - x / 48.0 + x * x / 3840.0 - x**3 / 645120.0,
                      jnp.sin(0.5 * t) / t)
        return c, s
    cu, su = half_angle(jnp.sum(u * u, -1))
    cv, sv = half_angle(jnp.sum(v * v, -1))
    a, b = -su[..., None] * u, sv[..., None] * v
    w = cu * cv - jnp.sum(a * b, -1)
    n = cu[..., None] * b + cv[..., None] * a + jnp.cross(a, b)
    y = jnp.sum(n * n, -1)
    small = (y < SMALL) & (w > 0.0)
    s = jnp.sqrt(jnp.where(small, 1.0, y))
    factor = jnp.where(small, 2.0 * (1.0 + y / 6.0 + 3.0 * y * y / 40.0 + 5.0 * y**3 / 112.0),
                       2.0 * jnp.arctan2(s, w) / s)
    return factor[..., None] * n


def matrix_relative_rotation(u, v):
    """The engine's joint rotation (``relative_joint_rotation``) with identity maps."""
    eye = jnp.eye(3, dtype=u.dtype)
    return relative_joint_rotation(u, v, eye, eye, False)


def newton_pass_costs(structure, params, control, path, step) -> list[float]:
    """Per-member microseconds of one Newton pass of the engine under ``vmap``, each batch
    size of ``BATCHES``: the whole ``jt.equilibrium`` call with ``max_steps=1`` less the same
    call with ``max_steps=0`` (start and post-processing), from the solution at ``step - 1``
    to the displacement of ``step``."""
    initial = jax.tree_util.tree_map(lambda x: x[step - 1], path)
    displacement = control.displacements[step]

    def solve(pressure, max_steps):
        member = eqx.tree_at(lambda q: q.pressure, params,
                             jnp.full_like(params.pressure, pressure))
        return jt.equilibrium(structure, member, control, displacement, initial,
                              jt.NewtonKKT(max_steps=max_steps)).iterations

    costs = []
    for batch in BATCHES:
        pressures = bench_solver.PRESSURE * jnp.linspace(0.99, 1.01, batch)
        seconds = {}
        for max_steps in (1, 0):
            program = jax.jit(jax.vmap(lambda pr, max_steps=max_steps: solve(pr, max_steps)))
            if max_steps and not bool(jnp.all(program(pressures) == 1)):
                raise RuntimeError("a member did not take its Newton step")
            seconds[max_steps] = median_seconds(program, pressures)
        costs.append((seconds[1] - seconds[0]) / batch * 1e6)
    return costs


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "profile_batch_pieces.txt")
    args = parser.parse_args(argv)
    lines: list[str] = []

    def report(text=""):
        print(text, flush=True)
        lines.append(text)

    structure, params, _, control, _, _ = bench_solver.build_problem()
    path = jt.solve_path(structure, params, control)
    step = 25
    state = jax.tree_util.tree_map(lambda x: x[step], path.state)
    lam = path.multipliers[step]
    geometry = tube_reference_geometry(structure, params)
    ctrl = (control.direction, control.displacements[step])
    z0, unravel = ravel_pytree(state)

    def objective(z, p):
        out = _model_objective(unravel(z), (p, geometry, ctrl), structure=structure,
                               control_node=control.node)
        return [jnp.reshape(x, (-1,)) for x in out]

    n, m = z0.size, lam.size
    k = objective(z0, params)[0].size

    def rows(z, p):
        parts, pull = jax.vjp(lambda zz: objective(zz, p)[0], z)
        (part_grads,) = jax.vmap(pull)(jnp.eye(k))
        c, pull_c = jax.vjp(lambda zz: objective(zz, p)[1], z)
        (jacobian,) = jax.vmap(pull_c)(jnp.eye(m))
        return parts, c, part_grads, jacobian

    pieces = {
        "energy terms": lambda z, mult, p: objective(z, p)[0],
        "energy gradient": lambda z, mult, p: jax.grad(lambda zz: jnp.sum(objective(zz, p)[0]))(z),
        "stopping-rule rows": lambda z, mult, p: rows(z, p),
        "Hessian blocks": lambda z, mult, p: _model_hessian(unravel(z), mult, (p, geometry, ctrl),
                                                         structure=structure,
                                                         control_node=control.node),
        # (a well-conditioned stand-in of the KKT matrix's size, one per member)
        "dense KKT solve": lambda z, mult, p: jnp.linalg.solve(
            jnp.eye(n + m) * (2.0 + 0.0 * p.pressure[0]) + 0.01, jnp.ones(n + m)),
    }
    topology = structure.spring_joint_topology()
    parent, child = np.asarray(topology.parent_segment), np.asarray(topology.child_segment)
    phi = state["segment_rotation"]
    pair = jnp.concatenate([phi[np.maximum(parent, 0)], phi[child]], axis=1)
    nodes = np.asarray(topology.node)

    def joint_blocks(p, rotation):
        law, torsion, pressure = p.bending_laws[0], p.torsion_laws[0], p.pressure[0]

        def energy(x, pm, cm, grounded, length, radius):
            u, v = pm @ x[:3], cm @ x[3:]
            theta = jnp.where(grounded, v, rotation(u, v))
            kappa = theta / length
            return length * (law.energy_density(kappa[0]**2 + kappa[1]**2, pressure, radius)
                             + torsion.energy_density(kappa[2]**2, pressure, radius))
        return jax.vmap(jax.hessian(energy))(pair, geometry.joint_parent_map,
                                             geometry.joint_child_map, parent == -1,
                                             geometry.joint_tributary,
                                             p.node_radius[nodes])

    def law_only(p):
        law, pressure = p.bending_laws[0], p.pressure[0]
        return jax.vmap(jax.hessian(lambda x, r: law.energy_density(
            (x[0]**2 + x[1]**2) / 0.05**2, pressure, r)))(pair[:, :3], p.node_radius[nodes])

    def rotation_only(p, rotation):
        return jax.vmap(jax.hessian(lambda x, pm, cm: p.pressure[0] * jnp.sum(
            rotation(pm @ x[:3], cm @ x[3:])**2)))(pair, geometry.joint_parent_map,
                                                  geometry.joint_child_map)

    # The engine's joint rotation is the matrix route: check the what-if against it.
    engine = relative_joint_rotation(pair[:, :3], pair[:, 3:], geometry.joint_parent_map,
                                     geometry.joint_child_map, (parent == -1)[:, None])
    u = jnp.einsum("jab,jb->ja", geometry.joint_parent_map, pair[:, :3])
    v = jnp.einsum("jab,jb->ja", geometry.joint_child_map, pair[:, 3:])
    what_if = jnp.where((parent == -1)[:, None], v, quaternion_relative_rotation(u, v))
    blocks_m, blocks_q = (joint_blocks(params, r) for r in (matrix_relative_rotation,
                                                            quaternion_relative_rotation))
    report(f"bench_solver.py's curve at step {step} of 50: n = {n} unknowns, m = {m} "
           f"constraints, {k} energy terms, {len(parent)} spring joints")
    report(f"quaternion what-if against the engine's joint rotations: "
           f"{float(jnp.max(jnp.abs(what_if - engine))):.1e} rad; joint Hessian blocks "
           f"{float(jnp.max(jnp.abs(blocks_q - blocks_m)) / jnp.max(jnp.abs(blocks_m))):.1e} "
           f"relative")
    more = {
        "joint blocks (jax.hessian, matrices)": lambda z, mult, p: joint_blocks(
            p, matrix_relative_rotation),
        "  the law's part alone": lambda z, mult, p: law_only(p),
        "  the rotation's part alone": lambda z, mult, p: rotation_only(
            p, matrix_relative_rotation),
        "joint blocks (quaternion what-if)": lambda z, mult, p: joint_blocks(
            p, quaternion_relative_rotation),
        "  the rotation's part alone (q.)": lambda z, mult, p: rotation_only(
            p, quaternion_relative_rotation),
    }
    pass_costs = newton_pass_costs(structure, params, control, path, step)
    report("per-member microseconds under jax.vmap (median of 30 calls of one jitted program):")
    report(f"{'piece':36s}" + "".join(f"{'batch ' + str(b):>12s}" for b in BATCHES))
    table = {name: [] for name in (*pieces, *more)}
    for batch in BATCHES:
        members = jax.vmap(lambda pr, r: eqx.tree_at(
            lambda q: (q.pressure, q.node_radius), params,
            (jnp.full_like(params.pressure, pr), jnp.full_like(params.node_radius, r))))(
            jnp.linspace(1e4, 5e4, batch), jnp.linspace(0.05, 0.1, batch))
        z_b, lam_b = jnp.tile(z0, (batch, 1)), jnp.tile(lam, (batch, 1))
        for name, fn in {**pieces, **more}.items():
            program = jax.jit(jax.vmap(fn))
            table[name].append(median_seconds(program, z_b, lam_b, members) / batch * 1e6)
    for name, values in table.items():
        report(f"{name:36s}" + "".join(f"{v:12.1f}" for v in values))
    report(f"{'one Newton pass of the engine':36s}" + "".join(f"{v:12.1f}" for v in pass_costs))
    report(f"  (jt.equilibrium from step {step - 1}'s solution to step {step}'s displacement, "
           f"max_steps=1 less max_steps=0, members 1 % apart in pressure: the same work per "
           f"member; batch 1 is what a loop of single solves pays per pass)")
    report("  throughput of a batched pass over a single one: "
           + ", ".join(f"batch {b} {pass_costs[0] / c:.2f}x"
                       for b, c in zip(BATCHES[1:], pass_costs[1:])))
    one, five, _ = os.getloadavg()
    report(f"load average {one:.1f} / {five:.1f} on {os.cpu_count()} cores; jax "
           f"{jax.__version__}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
