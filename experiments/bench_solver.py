"""Solver benchmark: warm run times and compile times of jaxtube's Newton-KKT solver on CPU.

Cases (a 1 m, 20-segment 3-D cantilever, r = 75 mm, p = 0.2 bar, spline law sampled from
the tension-field law with E t = 150 kN/m; Breukels & Ockels 2008):

- (a) one static solve, ``jt.equilibrium``, tip force 60 % of the wrinkling load;
- (b) a 50-step displacement-controlled curve through collapse, ``jt.solve_path``;
- (c) ``jax.vmap`` of such curves over a pressure x radius grid (0.1-0.5 bar x 50-100 mm),
  against a Python loop of the single curve over the same members in the same run, for the
  default solver with the dense and the sparse KKT route, and ``jt.map_members`` of the
  default solver's curve (the members split over the process's devices, ``--cpu-devices N``,
  and solved one after another on each: ``batch_case.py``); ``--batch-only`` runs (c) alone;
- a straightforward ``scipy.optimize.minimize(method="SLSQP")`` implementation of the same
  energy in numpy (finite-difference gradients, displacement control as an equality
  constraint), timed in the same process, as the baseline of (b).

Then a short profile of one Newton iteration (energy, gradient, Hessian, the KKT solve).

This is a script, not a test. Run from the repository root::

    python -m experiments.bench_solver            # full mode, a few minutes
    python -m experiments.bench_solver --quick    # fewer repeats, tiny batch (CI)
    python -m experiments.bench_solver --batch-only --batch 32 --cpu-devices 2 \
        --out experiments/results/bench_solver_batch.txt

The output is printed and written to ``experiments/results/bench_solver.txt`` (``--out``).
Timings are medians over repeats of warm (compiled) calls; compile times are measured
separately with ``jax.jit(f).lower(...).compile()``. The machine load
(``os.getloadavg()``) and this process's CPU share are printed next to the timings, since
on a shared machine they are what the numbers must be read against.
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import math
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

if "--cpu-devices" in sys.argv:  # read by jaxtube at import, before JAX starts
    os.environ["JAXTUBE_CPU_DEVICES"] = sys.argv[sys.argv.index("--cpu-devices") + 1]

import equinox as eqx
import jax
import jax.numpy as jnp
import scipy
import scipy.optimize
from jax.flatten_util import ravel_pytree

import jaxtube as jt

# Only for the what-if in the profile (3x3 products swapped for jnp.matmul, then restored).
import jaxtube._mechanics.energy as _energy
import jaxtube._mechanics.hessian as _hessian
import jaxtube._mechanics.kinematics as _kinematics
import jaxtube._rotation as _rotation
from experiments.batch_case import measure_batches

# --------------------------------------------------------------------------------------------
# The problem
# --------------------------------------------------------------------------------------------

LENGTH = 1.0  # m
RADIUS = 0.075  # m
PRESSURE = 2.0e4  # Pa (0.2 bar)
WALL_MODULUS = 150.0e3  # E t [N/m]
POISSON = 0.3
SEGMENTS = 20
LOAD_FRACTION = 0.6  # tip force of case (a), fraction of the wrinkling load
STEPS = 50
MAX_DEFLECTION = 0.4  # m, 40 % of the length: well into the collapse plateau
GRID_PRESSURE = (1.0e4, 5.0e4, 40)  # Pa: 0.1-0.5 bar
GRID_RADIUS = (0.05, 0.10, 25)  # m; 40 x 25 = 1000 curves

TARGET_STATIC = 1e-3  # s
TARGET_PATH = 40e-3  # s (issue 13)
TARGET_BATCH = 10.0  # s for 1000 curves (issue 13), and >= 8x a loop of single curves
TARGET_SPEEDUP = 50.0  # (b) vs the scipy baseline


def wrinkling_load(pressure, radius, length=LENGTH):
    """Tip load at which the root section wrinkles: ``M_w / L = pi p r^3 / (2 L)`` [N]."""
    return math.pi * pressure * radius**3 / (2.0 * length)


def collapse_load(pressure, radius, length=LENGTH):
    """Comer-Levy collapse tip load ``M_c / L = pi p r^3 / L`` [N] (small deflection)."""
    return math.pi * pressure * radius**3 / length


def build_problem():
    bending_law = jt.SplineLaw.from_tension_field(WALL_MODULUS, PRESSURE, RADIUS)
    # Thin isotropic tube: GJ = EI / (1 + nu). Torsion is not loaded here (planar tip load);
    # the linear law keeps the reference GJ over the whole grid of case (c).
    bending_stiffness = math.pi * WALL_MODULUS * RADIUS**3
    torsion_law = jt.LinearLaw(bending_stiffness / (1.0 + POISSON))
    structure, params = jt.cantilever(LENGTH, RADIUS, PRESSURE, SEGMENTS, bending_law,
                                      torsion_law)
    tip = structure.node_id("tube:end")
    load = LOAD_FRACTION * wrinkling_load(PRESSURE, RADIUS)
    loaded = eqx.tree_at(lambda p: p.node_force, params,
                         params.node_force.at[tip].set(jnp.array([0.0, 0.0, -load])))
    displacements = jnp.linspace(0.0, MAX_DEFLECTION, STEPS + 1)[1:]
    control = jt.DisplacementControl(tip, [0.0, 0.0, -1.0], displacements)
    return structure, params, loaded, control, tip, load


# --------------------------------------------------------------------------------------------
# Output and timing helpers
# --------------------------------------------------------------------------------------------


class Report:
    """Prints lines and keeps them for the results file."""

    def __init__(self):
        self.lines: list[str] = []

    def __call__(self, text: str = "") -> None:
        print(text, flush=True)
        self.lines.append(text)

    def write(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("\n".join(self.lines) + "\n")


def source_fingerprint() -> str:
    """Short hash of jaxtube's sources: the package changes fast and has no commits yet."""
    digest = hashlib.sha256()
    for path in sorted(Path(jt.__file__).parent.rglob("*.py")):
        digest.update(path.read_bytes())
    return digest.hexdigest()[:12]


def load_text() -> str:
    one, five, fifteen = os.getloadavg()
    return (f"load average {one:.2f} / {five:.2f} / {fifteen:.2f} "
            f"(1/5/15 min, {os.cpu_count()} CPUs)")


class Timing:
    """Warm timings of one callable: median, min, and this process's CPU share."""

    def __init__(self, walls, cpus, load):
        self.walls = np.asarray(walls)
        self.median = float(np.median(self.walls))
        self.best = float(np.min(self.walls))
        self.cpu_share = float(np.sum(cpus) / np.sum(walls))
        self.load = load
        self.repeats = len(walls)

    def text(self, unit=1e-3, name="ms") -> str:
        return (f"median {self.median / unit:.4g} {name}, min {self.best / unit:.4g} {name} "
                f"over {self.repeats} repeats; CPU share {self.cpu_share:.2f}; "
                f"1-min load {self.load:.2f}")


def time_warm(fn, *args, repeats: int, warmup: int = 1) -> tuple[Timing, object]:
    out = None
    for _ in range(warmup):
        out = jax.block_until_ready(fn(*args))
    walls, cpus = [], []
    for _ in range(repeats):
        cpu0, wall0 = time.process_time(), time.perf_counter()
        out = jax.block_until_ready(fn(*args))
        walls.append(time.perf_counter() - wall0)
        cpus.append(time.process_time() - cpu0)
    return Timing(walls, cpus, os.getloadavg()[0]), out


def compile_timed(fn, *args):
    """``(compiled, trace_and_lower_seconds, xla_compile_seconds, hlo_lines)``."""
    start = time.perf_counter()
    lowered = jax.jit(fn).lower(*args)
    lowered_at = time.perf_counter()
    compiled = lowered.compile()
    done = time.perf_counter()
    try:
        hlo_lines = len(compiled.as_text().splitlines())
    except Exception:  # as_text is best effort
        hlo_lines = -1
    return compiled, lowered_at - start, done - lowered_at, hlo_lines


def plateau_check(displacement, force, pressure, radius):
    """Last-step tangent stiffness over the initial one, and the peak force over the
    Comer-Levy collapse load. A plateau: the ratio is small (the curve has gone flat)."""
    initial = force[0] / displacement[0]
    final = (force[-1] - force[-2]) / (displacement[-1] - displacement[-2])
    return final / initial, float(np.max(force)) / collapse_load(pressure, radius)


# --------------------------------------------------------------------------------------------
# Baseline: the same energy in numpy, minimised by scipy's SLSQP
# --------------------------------------------------------------------------------------------


class NumpyCantilever:
    """Rigid-segment cantilever in plain numpy, as a user would write it for scipy.

    Unknowns: the ``[S, 3]`` joint rotation vectors (the clamped root is not an unknown).
    ``Q_0 = F_0 exp(theta_0)``, ``Q_s = Q_{s-1} exp(theta_s)`` (straight reference, so the
    reference relative rotations are identities), segment ``s`` spans ``Q_s (h e_3)``.
    Joint energy ``l_j [W_b(kappa_1^2 + kappa_2^2) + GJ kappa_3^2 / 2]``, ``kappa = theta / l``,
    tributary ``l = h`` between segments and ``h / 2`` at the clamp (as in jaxtube). The
    bending energy density is the same spline (pivots, knot slopes, pivot energies taken from
    the jaxtube law at this pressure and radius), re-evaluated here in numpy.
    """

    def __init__(self, law, torsion_stiffness, pressure, radius, segments, length):
        spline = law._coefficients(jnp.asarray(pressure), jnp.asarray(radius))
        self.knots = np.asarray(spline.curvatures)
        self.moments = np.asarray(spline.moments)
        self.slopes = np.asarray(spline.slopes)
        self.energies = np.asarray(spline.energies)
        self.linear = float(spline.linear_coefficient)
        self.cubic = float(spline.cubic_coefficient)
        self.torsion_stiffness = float(torsion_stiffness)
        self.segments = segments
        self.segment_length = length / segments
        self.tributary = np.full(segments, self.segment_length)
        self.tributary[0] = 0.5 * self.segment_length
        axis = np.array([1.0, 0.0, 0.0])
        d1 = np.array([0.0, 0.0, 1.0])
        self.root_frame = np.stack([d1, np.cross(axis, d1), axis], axis=1)
        self.tip_reference = length * axis

    def bending_energy_density(self, curvature_sq):
        knots, count = self.knots, self.knots.size
        first_sq = knots[0] ** 2
        beyond = curvature_sq > first_sq
        kappa = np.sqrt(np.where(beyond, curvature_sq, first_sq))
        inner = 0.5 * self.linear * curvature_sq + 0.25 * self.cubic * curvature_sq**2
        i = np.clip(np.searchsorted(knots, kappa, side="right") - 1, 0, count - 1)
        nxt = np.minimum(i + 1, count - 1)
        on_tail = i == count - 1
        k0, m0, d0, e0 = knots[i], self.moments[i], self.slopes[i], self.energies[i]
        k1 = np.where(on_tail, 2.0 * knots[-1], knots[nxt])
        m1, d1 = self.moments[nxt], self.slopes[nxt]
        h = k1 - k0
        t = (kappa - k0) / h
        hermite = e0 + h * ((0.5 * t**4 - t**3 + t) * m0
                            + (0.25 * t**4 - 2.0 / 3.0 * t**3 + 0.5 * t**2) * h * d0
                            + (-0.5 * t**4 + t**3) * m1 + (0.25 * t**4 - t**3 / 3.0) * h * d1)
        tail = e0 + m0 * (kappa - k0) + 0.5 * d0 * (kappa - k0) ** 2
        return np.where(beyond, np.where(on_tail, tail, hermite), inner)

    @staticmethod
    def rotation_matrices(theta):
        angle_sq = np.sum(theta * theta, axis=1)
        small = angle_sq < 1e-8
        angle = np.sqrt(np.where(small, 1.0, angle_sq))
        a = np.where(small, 1.0 - angle_sq / 6.0, np.sin(angle) / angle)
        b = np.where(small, 0.5 - angle_sq / 24.0, (1.0 - np.cos(angle)) / angle**2)
        x, y, z = theta[:, 0], theta[:, 1], theta[:, 2]
        zero = np.zeros_like(x)
        k = np.stack([np.stack([zero, -z, y], -1), np.stack([z, zero, -x], -1),
                      np.stack([-y, x, zero], -1)], axis=1)
        return np.eye(3) + a[:, None, None] * k + b[:, None, None] * (k @ k)

    def tip_position(self, unknowns):
        rotations = self.rotation_matrices(unknowns.reshape(self.segments, 3))
        frame = self.root_frame
        tip = np.zeros(3)
        for rotation in rotations:
            frame = frame @ rotation
            tip = tip + self.segment_length * frame[:, 2]
        return tip

    def energy(self, unknowns):
        theta = unknowns.reshape(self.segments, 3)
        curvature = theta / self.tributary[:, None]
        bend = self.bending_energy_density(curvature[:, 0] ** 2 + curvature[:, 1] ** 2)
        twist = 0.5 * self.torsion_stiffness * curvature[:, 2] ** 2
        return float(np.sum(self.tributary * (bend + twist)))


def scipy_curve(model: NumpyCantilever, displacements, direction):
    """The displacement-controlled curve by SLSQP, each step warm-started from the last.

    Returns forces (the constraint's multiplier: with scipy's ``grad E = lambda grad c``
    and ``c = (x - X) . d - u``, the actuator force is ``dE*/du = lambda``), success flags,
    iterations and the final unknowns of every step.
    """
    unknowns = np.zeros(3 * model.segments)
    forces, success, iterations = [], [], []
    for value in np.asarray(displacements):
        constraint = {
            "type": "eq",
            "fun": lambda x, v=value: np.array(
                [np.dot(model.tip_position(x) - model.tip_reference, direction) - v]),
        }
        result = scipy.optimize.minimize(model.energy, unknowns, method="SLSQP",
                                         constraints=[constraint],
                                         options={"ftol": 1e-12, "maxiter": 500})
        unknowns = result.x
        forces.append(float(result.multipliers[0]))
        success.append(bool(result.success))
        iterations.append(int(result.nit))
    return np.array(forces), np.array(success), np.array(iterations)


# --------------------------------------------------------------------------------------------
# The cases
# --------------------------------------------------------------------------------------------

DEFAULT_SETTING = "dense"  # what jt.NewtonKKT() does on this 67-unknown system


def batch_case_report(report, structure, params, control, batch, repeats):
    """Case (c): ``batch`` grid members batched and looped, for each solver setting."""
    grid_size = GRID_PRESSURE[2] * GRID_RADIUS[2]
    pressures = np.linspace(*GRID_PRESSURE)
    radii = np.linspace(*GRID_RADIUS)
    grid_p, grid_r = (a.ravel() for a in np.meshgrid(pressures, radii, indexing="ij"))
    members = np.unique(np.round(np.linspace(0, grid_size - 1, batch)).astype(int))
    batch = members.size
    report(f"(c) jax.vmap of curve (b) over a {GRID_PRESSURE[2]} x {GRID_RADIUS[2]} grid "
           f"(p {pressures[0] / 1e5:g}-{pressures[-1] / 1e5:g} bar x r "
           f"{radii[0] * 1e3:g}-{radii[-1] * 1e3:g} mm = {grid_size} curves), against a Python "
           "loop of the single curve over the same members, in the same run")
    report(f"    {batch} grid members spread over the grid (corners included) are run, batched "
           f"and looped; times for {grid_size} curves are scaled by {grid_size}/{batch} "
           f"(medians of {repeats} interleaved repeats)")
    results = measure_batches(report, structure, params, control, grid_p, grid_r, members,
                              repeats, compile_timed)
    report("    scaled to 1000 curves (batched, loop, batched throughput over the loop's):")
    for name, r in results.items():
        report(f"      {name:22s} {r['batch'] * grid_size / batch:7.1f} s  "
               f"{r['loop'] * grid_size / batch:7.1f} s  {r['loop'] / r['batch']:5.2f}x")
    return results, batch


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="fewer repeats and a tiny batch for (c) (CI smoke run)")
    parser.add_argument("--batch", type=int, default=None,
                        help="curves actually run in case (c) (default 8, quick: 2); the time "
                             "for 1000 is scaled from it")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).resolve().parent / "results" / "bench_solver.txt")
    parser.add_argument("--cpu-devices", default=None,
                        help="CPU devices of the process (JAXTUBE_CPU_DEVICES: N or auto), "
                             "over which (c)'s map_members setting splits the curves")
    parser.add_argument("--batch-only", action="store_true",
                        help="run case (c) alone (the batch against the loop of single curves)")
    args = parser.parse_args(argv)
    quick = args.quick
    repeats_static = 5 if quick else 30
    repeats_batch = 1 if quick else 3
    repeats_path = 2 if quick else 4
    repeats_scipy = 1  # about 4 min per curve on this machine
    repeats_piece = 5 if quick else 25
    batch = args.batch if args.batch is not None else (4 if quick else 32)
    grid_size = GRID_PRESSURE[2] * GRID_RADIUS[2]

    report = Report()
    started = time.perf_counter()
    report("jaxtube solver benchmark (experiments/bench_solver.py"
           + (" --quick)" if quick else ")"))
    report(f"date {datetime.datetime.now().isoformat(timespec='seconds')}; "
           f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs; "
           f"python {platform.python_version()}, jax {jax.__version__} "
           f"({jax.default_backend()}), numpy {np.__version__}, scipy {scipy.__version__}")
    report(f"jaxtube sources sha256[:12] {source_fingerprint()} ({Path(jt.__file__).parent})")
    report(f"start: {load_text()}; {jax.device_count()} device(s)")
    report(f"problem: {SEGMENTS}-segment 3-D cantilever, L = {LENGTH} m, r = {RADIUS} m, "
           f"p = {PRESSURE / 1e5} bar, spline law from the tension-field law, "
           f"E t = {WALL_MODULUS / 1e3:g} kN/m; 63 unknowns (root position + 20 rotation "
           "vectors), 3 support constraints (+1 under displacement control)")
    report()

    structure, params, loaded, control, tip, load = build_problem()
    results = {}
    if args.batch_only:
        batch_case_report(report, structure, params, control, batch, repeats_batch)
        report(f"machine load at the end: {load_text()}; total wall time "
               f"{time.perf_counter() - started:.0f} s")
        report.write(args.out)
        print(f"\nwritten to {args.out}")
        return 0

    # ---- (a) one static solve ------------------------------------------------------------
    report(f"(a) static solve, tip force {load:.3f} N = {LOAD_FRACTION:.0%} of the wrinkling "
           "load, from the undeformed state")
    static_fn = lambda p: jt.equilibrium(structure, p)  # noqa: E731
    static, lower_s, compile_s, hlo = compile_timed(static_fn, loaded)
    timing, solution = time_warm(static, loaded, repeats=repeats_static)
    deflection = -float(solution.node_position[tip, 2])
    linear_deflection = load * LENGTH**3 / (3.0 * math.pi * WALL_MODULUS * RADIUS**3)
    report(f"    converged {bool(solution.converged)} in {int(solution.iterations)} Newton "
           f"steps; tip deflection {deflection * 1e3:.3f} mm "
           f"(linear beam P L^3 / 3 EI: {linear_deflection * 1e3:.3f} mm)")
    report(f"    compile: trace+lower {lower_s:.1f} s + XLA {compile_s:.1f} s "
           f"({hlo} lines of optimised HLO)")
    report(f"    warm: {timing.text()}")
    results["a"] = (timing, lower_s + compile_s)
    compile_split = {"a": (lower_s, compile_s)}
    report()

    # ---- (b) one displacement-controlled curve -------------------------------------------
    displacements = np.asarray(control.displacements)
    report(f"(b) displacement-controlled curve: {STEPS} steps of "
           f"{displacements[0] * 1e3:.0f} mm, tip driven down to {MAX_DEFLECTION * 1e3:.0f} mm")
    path_fn = lambda p: jt.solve_path(structure, p, control)  # noqa: E731
    path, lower_p, compile_p, hlo = compile_timed(path_fn, params)
    timing, sols = time_warm(path, params, repeats=repeats_path)
    force = np.asarray(sols.control_force)
    converged = np.asarray(sols.converged)
    newton_steps = np.asarray(sols.iterations)
    root_regime = np.asarray(sols.joint_regime)[:, 0]
    flat_ratio, peak_ratio = plateau_check(displacements, force, PRESSURE, RADIUS)
    plateau_ok = flat_ratio < 0.05 and 0.9 < peak_ratio < 1.2
    report(f"    all steps converged: {bool(converged.all())} ({int(converged.sum())}/{STEPS}); "
           f"Newton steps: {int(newton_steps.sum())} in all, per step "
           f"{int(newton_steps.min())}-{int(newton_steps.max())}")
    report("    force [N] at u = " + ", ".join(
        f"{displacements[k] * 1e3:.0f} mm: {force[k]:.2f}" for k in (0, 4, 9, 19, 29, 39, 49)))
    report(f"    plateau: last-step tangent stiffness = {flat_ratio:.3f} x initial; peak force "
           f"= {peak_ratio:.3f} x Comer-Levy collapse load pi p r^3 / L "
           f"({collapse_load(PRESSURE, RADIUS):.2f} N); root section collapsed (regime 2) from "
           f"u = {displacements[np.argmax(root_regime == 2)] * 1e3:.0f} mm -> "
           f"{'plateau reached' if plateau_ok else 'NO clear plateau'}")
    report(f"    compile: trace+lower {lower_p:.1f} s + XLA {compile_p:.1f} s "
           f"({hlo} lines of optimised HLO)")
    report(f"    warm: {timing.text()}")
    hessians_b = int(newton_steps.sum()) + STEPS  # the converged check also linearises
    report(f"    -> {timing.median / hessians_b * 1e3:.1f} ms per linearisation "
           f"({hessians_b} = Newton steps + one converged check per load step)")
    results["b"] = (timing, lower_p + compile_p)
    compile_split["b"] = (lower_p, compile_p)
    path_force = force
    path_hessians = hessians_b
    report()

    # ---- scipy baseline of (b) -----------------------------------------------------------
    scipy_steps = 10 if quick else STEPS
    report("(b') baseline: the same energy in numpy, scipy.optimize.minimize(method='SLSQP'), "
           "2-point finite-difference gradients (scipy's default), displacement as an equality "
           "constraint, each step warm-started from the last, ftol 1e-10 (looser ftol barely "
           "shortens the run but loses force accuracy)")
    if scipy_steps < STEPS:
        report(f"    --quick: only the first {scipy_steps} steps are solved; the time is scaled "
               f"by {STEPS}/{scipy_steps} (an estimate: later steps take more iterations)")
    law = params.bending_laws[0]
    model = NumpyCantilever(law, params.torsion_laws[0].stiffness, PRESSURE, RADIUS, SEGMENTS,
                            LENGTH)
    # The numpy energy is the jaxtube energy: check at a random state.
    geometry = jt.reference_geometry(structure, params)
    rng = np.random.default_rng(0)
    theta = 0.05 * rng.standard_normal((SEGMENTS, 3))
    # The numpy model's unknowns are joint (relative) rotations; jaxtube's are segment
    # rotations from the reference: for a straight chain phi_k = log(exp(theta_1)...exp(theta_k)).
    products, current = [], np.eye(3)
    for t in theta:
        current = current @ np.asarray(jt.rotation_matrix(jnp.asarray(t)))
        products.append(current)
    phi = np.asarray(jt.rotation_vector(jnp.asarray(np.stack(products))))
    state = {"root_position": params.node_position[structure.root_node],
             "segment_rotation": jnp.asarray(phi)}
    energy_jt = float(jt.total_energy(structure, params, geometry, state))
    energy_np = model.energy(theta.ravel())
    tip_jt = np.asarray(jt.configuration(structure, geometry, state).node_position[tip])
    report(f"    energy check at a random state: jaxtube {energy_jt:.12g} J, numpy "
           f"{energy_np:.12g} J; tip position differs by "
           f"{np.max(np.abs(tip_jt - model.tip_position(theta.ravel()))):.1e} m")
    evaluations = 200
    wall0 = time.perf_counter()
    for _ in range(evaluations):
        model.energy(theta.ravel())
    numpy_energy = (time.perf_counter() - wall0) / evaluations
    wall0 = time.perf_counter()
    for _ in range(evaluations):
        model.tip_position(theta.ravel())
    numpy_tip = (time.perf_counter() - wall0) / evaluations
    report(f"    numpy cost per evaluation: energy {numpy_energy * 1e6:.0f} us, tip position "
           f"(constraint) {numpy_tip * 1e6:.0f} us")
    walls, cpus = [], []
    for _ in range(repeats_scipy):
        cpu0, wall0 = time.process_time(), time.perf_counter()
        scipy_force, scipy_success, scipy_iterations = scipy_curve(
            model, displacements[:scipy_steps], np.array([0.0, 0.0, -1.0]))
        walls.append(time.perf_counter() - wall0)
        cpus.append(time.process_time() - cpu0)
    scale = STEPS / scipy_steps
    scipy_timing = Timing(np.asarray(walls) * scale, np.asarray(cpus) * scale,
                          os.getloadavg()[0])
    relative = np.abs(scipy_force - path_force[:scipy_steps]) / np.abs(path_force[:scipy_steps])
    report(f"    all steps successful: {bool(scipy_success.all())} "
           f"({int(scipy_success.sum())}/{scipy_steps}); SLSQP iterations "
           f"{int(scipy_iterations.sum())} in all, per step {int(scipy_iterations.min())}-"
           f"{int(scipy_iterations.max())}")
    report(f"    force vs jaxtube: max relative difference {relative.max():.2e} "
           f"(median {np.median(relative):.2e}, at u = "
           f"{displacements[np.argmax(relative)] * 1e3:.0f} mm)")
    report(f"    time for the {STEPS}-step curve: {scipy_timing.text(1.0, 's')}"
           + (" (scaled)" if scipy_steps < STEPS else ""))
    results["scipy"] = scipy_timing
    report()

    # ---- (c) vmap over a pressure x radius grid ------------------------------------------
    batch_results, batch = batch_case_report(report, structure, params, control, batch,
                                             repeats_batch)
    timing_c = batch_results[DEFAULT_SETTING]
    best_c = min(batch_results, key=lambda name: batch_results[name]["batch"])
    results["c"] = (timing_c["batch"] * grid_size / batch, timing_c["compile_batched"],
                    batch_results[best_c]["batch"] * grid_size / batch, best_c)
    report()

    # ---- profile of one Newton iteration -------------------------------------------------
    report("profile: the pieces of one Newton iteration of (b), each jitted alone, warm, at a "
           "deformed state (63 unknowns, 4 constraints; reference geometry precomputed, as in "
           "the solver)")
    state0 = jt.initial_state(structure, params)
    flat0, unravel = ravel_pytree(state0)
    z_size = flat0.size
    flat_state = flat0.at[3:].set(jnp.asarray(0.02 * rng.standard_normal(flat0.size - 3)))
    multipliers = jnp.ones(4)
    root = structure.root_node

    def energy(z, p, g):
        return jt.total_energy(structure, p, g, unravel(z))

    def constraints(z, p, g):
        # The cantilever's constraints: the clamped root stays put; the tip is driven 0.2 m.
        state = unravel(z)
        moved = jt.configuration(structure, g, state).node_position[tip] - p.node_position[tip]
        return jnp.concatenate([state["root_position"] - p.node_position[root],
                                (jnp.dot(moved, control.direction) - 0.2)[None]])

    def gradient_parts(z, lam, p, g):
        def lagrangian(zz):
            e, c = energy(zz, p, g), constraints(zz, p, g)
            return e + jnp.dot(lam, c), (e, c)

        (_, (e, c)), gradient = jax.value_and_grad(lagrangian, has_aux=True)(z)
        return gradient, e, c

    def lagrangian(z, lam, p, g):
        return energy(z, p, g) + jnp.dot(lam, constraints(z, p, g))

    def lagrangian_shared(z, lam, p, g):
        # The same Lagrangian with one forward kinematics shared by energy and constraints.
        state = unravel(z)
        config = jt.configuration(structure, g, state)
        joints = _kinematics.spring_joints(structure, g, state)
        e = (_energy.strain_energy(joints, p)
             + _energy.load_potential(structure, g, config, p, state))
        moved = config.node_position[tip] - p.node_position[tip]
        c = jnp.concatenate([state["root_position"] - p.node_position[root],
                             (jnp.dot(moved, control.direction) - 0.2)[None]])
        return e + jnp.dot(lam, c)

    def solver_linearisation(z, lam, p, g):
        # What NewtonKKT does: one linearisation of (gradient, energy, constraints), pushed
        # through the identity, gives the Lagrangian Hessian and the constraint Jacobian.
        _, tangent = jax.linearize(lambda zz: gradient_parts(zz, lam, p, g), z)
        hessian, _, jacobian_t = jax.vmap(tangent)(jnp.eye(z.size))
        return hessian, jacobian_t

    def kkt_solve(hessian, jacobian, rhs):
        kkt = jnp.block([[hessian, jacobian.T],
                         [jacobian, jnp.zeros((jacobian.shape[0],) * 2)]])
        return jnp.linalg.solve(kkt, rhs)

    point = (flat_state, params, geometry)
    lagrange_point = (flat_state, multipliers, params, geometry)
    one_step_solver = jt.NewtonKKT(max_steps=1)

    def one_newton_step(p):
        return jt.equilibrium(structure, p, control, 0.05, solver=one_step_solver)

    names = {
        "energy": "energy E(z)",
        "gradient": "gradient jax.grad(E)",
        "trial": "Lagrangian gradient + E + c (line-search trial point)",
        "hessian": "Hessian jax.hessian(E) [63 x 63]",
        "linearisation": "dense autodiff linearisation: Hessian + Jacobian (linearize+vmap)",
        "assembled": "solver's Hessian: element-assembled (lagrangian_hessian)",
        "lagrangian": "jax.hessian(E + lam.c), kinematics in E and in c",
        "shared": "jax.hessian(E + lam.c), kinematics shared",
        "jacobian": "constraint Jacobian jax.jacfwd(c) [4 x 63]",
        "solve": "KKT assemble + jnp.linalg.solve [67 x 67]",
        "iteration": "whole Newton iteration: equilibrium(max_steps=1)",
        "matmul gradient": "what-if, 3x3 products as jnp.matmul: jax.grad(E)",
        "matmul hessian": "what-if, 3x3 products as jnp.matmul: jax.hessian(E)",
    }
    # Compile every piece first, then time them in interleaved rounds (one call of each
    # piece per round), so that a change of machine load hits all pieces alike.
    compiled_pieces = {}

    def add_piece(key, fn, fn_args):
        compiled, lower_t, compile_t, _ = compile_timed(fn, *fn_args)
        out = jax.block_until_ready(compiled(*fn_args))
        compiled_pieces[key] = (compiled, fn_args, lower_t, compile_t)
        return out

    add_piece("energy", energy, point)
    add_piece("gradient", jax.grad(energy), point)
    add_piece("trial", gradient_parts, lagrange_point)
    hessian_reference = add_piece("hessian", jax.hessian(energy), point)
    hessian_value, jacobian_t = add_piece("linearisation", solver_linearisation, lagrange_point)
    add_piece("lagrangian", jax.hessian(lagrangian), lagrange_point)

    def assembled(z, lam, p, g):
        ctrl = (tip, control.direction, jnp.asarray(0.2))
        return _hessian.lagrangian_hessian(structure, g, p, ctrl, unravel(z), lam)

    assembled_value = add_piece("assembled", assembled, lagrange_point)
    assembled_error = float(jnp.max(jnp.abs(assembled_value - hessian_value))
                            / jnp.max(jnp.abs(hessian_value)))
    try:
        add_piece("shared", jax.hessian(lagrangian_shared), lagrange_point)
    except AttributeError as error:  # private helpers renamed
        report(f"    shared-kinematics Hessian skipped: {error}")
    add_piece("jacobian", jax.jacfwd(constraints), point)
    add_piece("solve", kkt_solve, (hessian_value, jacobian_t.T, jnp.ones(z_size + 4)))
    add_piece("iteration", one_newton_step, (params,))

    # What-if: the same energy with the 3x3 products as jnp.matmul instead of the
    # broadcast-multiply-reduce of jaxtube._rotation.matmul3 / matvec3. Patched only while
    # tracing and compiling; the originals are restored right after.
    patched = [(m, n) for m in (_kinematics, _rotation) for n in ("matmul3", "matvec3")
               if hasattr(m, n)]
    matmul_note = "    what-if skipped: jaxtube no longer has matmul3/matvec3 where expected"
    if len(patched) == 4:
        saved = {(m, n): getattr(m, n) for m, n in patched}
        try:
            for module in (_kinematics, _rotation):
                module.matmul3 = jnp.matmul
                module.matvec3 = lambda a, v: jnp.matmul(a, v[..., None])[..., 0]
            add_piece("matmul gradient", jax.grad(energy), point)
            hessian_matmul = add_piece("matmul hessian", jax.hessian(energy), point)
        finally:
            for (module, name), value in saved.items():
                setattr(module, name, value)
        matmul_error = float(jnp.max(jnp.abs(hessian_matmul - hessian_reference))
                             / jnp.max(jnp.abs(hessian_reference)))
        matmul_note = f"    (the what-if Hessian equals jaxtube's to {matmul_error:.0e} relative)"

    walls = {key: [] for key in compiled_pieces}
    cpus = {key: [] for key in compiled_pieces}
    for _ in range(repeats_piece):
        for key, (compiled, fn_args, _, _) in compiled_pieces.items():
            cpu0, wall0 = time.process_time(), time.perf_counter()
            jax.block_until_ready(compiled(*fn_args))
            walls[key].append(time.perf_counter() - wall0)
            cpus[key].append(time.process_time() - cpu0)
    profile = {}
    for key, (_, _, lower_t, compile_t) in compiled_pieces.items():
        timing = Timing(walls[key], cpus[key], os.getloadavg()[0])
        profile[key] = (timing, lower_t, compile_t)
        report(f"    {names[key]:58s} {timing.median * 1e3:8.3f} ms (min "
               f"{timing.best * 1e3:7.3f})  compile {lower_t:4.1f} + {compile_t:4.1f} s")
    report(matmul_note)
    report(f"    (the assembled Hessian equals the dense autodiff one to {assembled_error:.0e} "
           "relative)")
    report(f"    ({repeats_piece} interleaved rounds; CPU share over all pieces "
           f"{sum(map(sum, cpus.values())) / sum(map(sum, walls.values())):.2f})")
    report(f"    end: {load_text()}")
    report()

    # ---- table ---------------------------------------------------------------------------
    timing_a, compile_a = results["a"]
    timing_b, compile_b = results["b"]
    scaled_c, compile_c, scaled_best_c, best_c = results["c"]
    rows = [
        ("(a) static solve", timing_a.median, f"{timing_a.median * 1e3:.1f} ms", compile_a,
         TARGET_STATIC, "<= 1 ms"),
        ("(b) 50-step curve", timing_b.median, f"{timing_b.median * 1e3:.0f} ms", compile_b,
         TARGET_PATH, "<= 40 ms"),
        (f"(c) vmap 1000 curves (from {batch})", scaled_c, f"{scaled_c:.0f} s", compile_c,
         TARGET_BATCH, "<= 10 s"),
        (f"(c) best: {best_c}", scaled_best_c, f"{scaled_best_c:.0f} s",
         batch_results[best_c]["compile_batched"], TARGET_BATCH, "<= 10 s"),
    ]
    report("results (warm medians; compile = trace+lower+XLA compile)")
    header = (f"{'case':34s} {'median':>10s} {'compile':>9s} {'target':>9s} "
              f"{'ratio to target':>16s}  verdict")
    report(header)
    report("-" * len(header))
    for name, value, shown, compile_time, target, target_text in rows:
        ratio = value / target
        verdict = "met" if ratio <= 1.0 else f"MISSED by {ratio:.1f}x"
        report(f"{name:34s} {shown:>10s} {compile_time:8.1f}s {target_text:>9s} "
               f"{ratio:15.1f}x  {verdict}")
    speedup = scipy_timing.median / timing_b.median
    verdict = "met" if speedup >= TARGET_SPEEDUP else (
        f"MISSED by {TARGET_SPEEDUP / speedup:.1f}x" if speedup > 0 else "MISSED")
    scipy_name = "(b) vs scipy SLSQP" + (" (est.)" if scipy_steps < STEPS else " (same curve)")
    report(f"{scipy_name:34s} {scipy_timing.median:9.2f}s {'-':>9s} "
           f"{'>= 50x':>9s} {speedup:14.2f}x  {verdict}  (jaxtube is {speedup:.2f}x "
           f"{'faster' if speedup >= 1 else 'as fast'}; forces agree to {relative.max():.1e})")
    report(f"machine load during the run: {load_text()}; total wall time "
           f"{time.perf_counter() - started:.0f} s")
    report()

    # ---- findings ------------------------------------------------------------------------
    def median(key):
        return profile[key][0].median

    def compile_total(key):
        return profile[key][1] + profile[key][2]

    iteration, linearisation = median("iteration"), median("linearisation")
    hessian, gradient, solve = median("hessian"), median("gradient"), median("solve")
    per_linearisation_b = timing_b.median / path_hessians
    xla_share = sum(x for _, x in compile_split.values()) / sum(
        t + x for t, x in compile_split.values())
    report("findings (numbers from this run)")
    assembled_t = median("assembled")
    report(f"1. The solver's Hessian is assembled from element Hessians (segment rotations as "
           f"unknowns: every load and constraint is separable by segment, every spring couples "
           f"two segments): {assembled_t * 1e3:.2f} ms, against {linearisation * 1e3:.1f} ms "
           f"for the dense forward-over-reverse linearisation of the same Lagrangian "
           f"({linearisation / assembled_t:.1f}x). A whole Newton iteration takes "
           f"{iteration * 1e3:.2f} ms; the KKT solve {solve * 1e3:.2f} ms, a gradient "
           f"{gradient * 1e3:.2f} ms, the energy {median('energy') * 1e3:.2f} ms. In (b) the "
           f"time per linearisation is {per_linearisation_b * 1e3:.2f} ms all-in.")
    report(f"2. The dense jax.hessian(E) costs {hessian / gradient:.0f}x one gradient for 63 "
           "unknowns: forward-over-reverse pushes all 63 tangents through every rotation of "
           "the structure, while the assembled Hessian differentiates 3- and 6-variable "
           f"element functions only. (The energy alone takes {median('energy') * 1e3:.2f} ms "
           f"warm vs {numpy_energy * 1e3:.2f} ms for the baseline's numpy energy: per-op "
           "overhead of small arrays.)")
    if "shared" in profile:
        report(f"3. The constraints redo the forward kinematics: the Lagrangian Hessian takes "
               f"{median('lagrangian') * 1e3:.1f} ms as the solver builds it (configuration() "
               f"in the energy and again in the constraints; the Jacobian of c alone "
               f"{median('jacobian') * 1e3:.1f} ms) but {median('shared') * 1e3:.1f} ms with "
               f"one shared configuration ({median('lagrangian') / median('shared'):.1f}x), vs "
               f"{hessian * 1e3:.1f} ms for the energy alone. "
               + ("A solver API where energy and constraints share one kinematics evaluation "
                  "would bank that." if median("lagrangian") > 1.2 * median("shared") else
                  "No clear gain in this run."))
    if "matmul hessian" in profile:
        gain = hessian / median("matmul hessian")
        report(f"4. 3x3 products: with jnp.matmul in place of matmul3/matvec3 the "
               f"Hessian takes {median('matmul hessian') * 1e3:.1f} ms instead of "
               f"{hessian * 1e3:.1f} ms ({gain:.1f}x), the gradient "
               f"{median('matmul gradient') * 1e3:.2f} ms instead of {gradient * 1e3:.2f} ms. "
               + ("The matmul3 docstring's premise (batched dot_general slow on CPU) does not "
                  "hold for this model's derivatives: cheap to try in _rotation.py."
                  if gain > 1.3 else "No clear gain: matmul3 is not the bottleneck in this "
                  "version of jaxtube."))
    else:
        report("4. (what-if on the 3x3 products skipped, see the profile)")
    report(f"5. Each load step ends with a pass that only confirms convergence: {STEPS} of the "
           f"{path_hessians} passes in (b) ({STEPS / path_hessians:.0%}). That pass computes each "
           "energy term's gradient and the constraint rows (the stopping rule needs them at "
           "the new point) and skips the Hessian, the KKT solve and the line search.")
    budget = TARGET_PATH / path_hessians
    report(f"6. Newton's step count is already low ({int(newton_steps.sum())} steps for 50 "
           f"load steps, {newton_steps.mean():.1f} per step); the (b) target allows "
           f"{budget * 1e3:.2f} ms per pass, against {per_linearisation_b * 1e3:.2f} ms "
           f"measured ({per_linearisation_b / budget:.2f}x the allowance).")
    default_c, best = batch_results[DEFAULT_SETTING], batch_results[best_c]
    report(f"7. vmap of {batch} curves: the default solver batched runs at "
           f"{default_c['loop'] / default_c['batch']:.2f}x the throughput of a loop of single "
           f"curves; the best setting ({best_c}) at {best['loop'] / best['batch']:.2f}x "
           f"(target >= 8x); lockstep while loops run {default_c['lockstep']} Newton steps vs "
           f"{default_c['steps']:.1f} needed per curve on average.")
    report(f"8. Compile time: (a) {compile_a:.0f} s, (b) {compile_b:.0f} s, (c) {compile_c:.0f} "
           f"s, {xla_share:.0%} of it in XLA (the rest tracing/lowering). The Hessian alone "
           f"compiles in {compile_total('hessian'):.0f} s, the solver's linearisation in "
           f"{compile_total('linearisation'):.0f} s, the gradient in "
           f"{compile_total('gradient'):.0f} s; one Newton body holds the linearisation, the "
           "trial-point gradient, the line-search merit and the post-processing, and every "
           "new structure or solver setting (static fields) recompiles all of it.")
    scaled_note = " (scaled from 10 steps)" if scipy_steps < STEPS else ""
    report(f"9. scipy SLSQP with finite differences in numpy needs {scipy_timing.median:.0f} s "
           f"for the curve{scaled_note} ({int(scipy_iterations.sum())} SLSQP iterations, each "
           f"about 60 energy and 60 constraint evaluations); jaxtube (b) is {speedup:.1f}x faster "
           f"({'meets' if speedup >= TARGET_SPEEDUP else 'short of'} the 50x target), and "
           f"the two agree to {relative.max():.1e} in force. The machine was shared (load "
           "and CPU share above), which inflates absolute times more than the ratios.")
    report.write(args.out)
    print(f"\nwritten to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
