"""Benchmark: a 1 m, r = 75 mm cantilever on a linear law under a sudden tip load, 1 s,
jaxtube (implicit Newmark on SO(3), rigid segments) against PyElastica (explicit
position Verlet, Cosserat rod), side by side in one process; and (``--kite``) the real-time
factor of the 140-segment tube kite under a sudden crown load.

Both rods have the same bending stiffness EI, mass per length and rotary inertia (a
thin-walled section, ``r^2 / 2`` per unit mass across the axis: PyElastica's solid-section
value is doubled), so both converge to the same continuum: Euler-Bernoulli with the
section's rotary inertia (a Rayleigh beam; its first frequency from the Rayleigh quotient of
the Euler-Bernoulli mode is the reference printed first). PyElastica's shear modulus is 2E
(stiff in shear, as the rigid segments are). Each code runs at the coarsest resolution
that puts its first-mode frequency within 0.5 % of that reference (``--convergence``
prints the tables the choice rests on): jaxtube 16 segments (modal error -0.18 %) and 35
steps a period (the average-acceleration rule's period elongation, ``omega_h h = 2
atan(omega h / 2)``: -0.27 %); PyElastica 200 elements (first order in the element length)
at the largest step that stays stable (4 us: 4.5 us diverges). Compared: the first-mode
frequency of the tip history (zero crossings about the mean) and its amplitude (half the
peak-to-peak swing), against each other and against the reference; wall times (jaxtube
warm: compiled before timing; PyElastica after a short warm-up run for numba). The last
line states the agreement and the wall-time ratio.

Run: ``python -m experiments.bench_dynamics [--quick] [--convergence] [--kite]`` (needs
the ``bench`` extra: ``pip install pyelastica``).
"""

from __future__ import annotations

import argparse
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import jaxtube as jt

LENGTH, RADIUS, STIFFNESS, MASS, TIP_LOAD = 1.0, 0.075, 300.0, 0.3, 1.0  # m, m, N m^2, kg/m, N
SEGMENTS, STEPS_PER_PERIOD = 16, 35  # jaxtube
ELEMENTS, ELASTICA_STEP = 200, 4e-6  # PyElastica [s]


def rayleigh_beam_frequency() -> float:
    """First frequency [Hz] of the clamped-free Rayleigh beam (Euler-Bernoulli with the
    rotary inertia ``mu r^2 / 2`` of a thin-walled section): the Rayleigh quotient
    ``EI int w''^2 / (mu int w^2 + mu r^2 / 2 int w'^2)`` of the Euler-Bernoulli mode
    ``w = cosh bx - cos bx - s (sinh bx - sin bx)``, ``bL = 1.8751`` (accurate to first order
    in ``(r / L)^2``)."""
    b = 1.8751040687 / LENGTH
    s = (np.cosh(b * LENGTH) + np.cos(b * LENGTH)) / (np.sinh(b * LENGTH) + np.sin(b * LENGTH))
    x = np.linspace(0.0, LENGTH, 20001)
    w = np.cosh(b * x) - np.cos(b * x) - s * (np.sinh(b * x) - np.sin(b * x))
    slope = b * (np.sinh(b * x) + np.sin(b * x) - s * (np.cosh(b * x) - np.cos(b * x)))
    curvature = b**2 * (np.cosh(b * x) + np.cos(b * x) - s * (np.sinh(b * x) + np.sin(b * x)))
    omega_sq = (STIFFNESS * np.trapezoid(curvature**2, x)
                / (MASS * np.trapezoid(w**2, x) + MASS * RADIUS**2 / 2 * np.trapezoid(slope**2, x)))
    return float(np.sqrt(omega_sq) / (2 * np.pi))


def tip_frequency_and_amplitude(time_s, tip_z):
    """Mean frequency from upward zero crossings about the mean [Hz], and half the
    peak-to-peak swing [m]."""
    swing = tip_z - 0.5 * (tip_z.max() + tip_z.min())
    up = np.flatnonzero((swing[:-1] < 0) & (swing[1:] >= 0))
    crossing = time_s[up] - swing[up] / (swing[up + 1] - swing[up]) * (time_s[1] - time_s[0])
    return (len(crossing) - 1) / (crossing[-1] - crossing[0]), 0.5 * np.ptp(tip_z)


def cantilever(segments):
    """The jaxtube cantilever (weightless) and its static equilibrium."""
    structure, params = jt.cantilever(LENGTH, RADIUS, 2e4, segments, jt.LinearLaw(STIFFNESS),
                                      jt.LinearLaw(STIFFNESS / 1.3), mass_per_length=MASS)
    params = eqx.tree_at(lambda p: p.gravity, params, jnp.zeros(3))
    return structure, params, jt.equilibrium(structure, params)


def run_jaxtube(segments, steps_per_period, duration, repeats):
    structure, params, static = cantilever(segments)
    first = float(jt.modes(structure, params, static, count=1).frequency[0])
    step = 1.0 / (steps_per_period * first)
    steps = int(round(duration / step))
    load = jt.dynamic_load(structure, params, {"tube:end": [0.0, 0.0, -TIP_LOAD]},
                           jt.StepFunction())
    run = jax.jit(lambda p: jt.simulate_dynamics(structure, p, step, steps, initial=static,
                                                 loads=(load,)))
    jax.block_until_ready(run(params))
    walls = []
    for _ in range(repeats):
        started = time.perf_counter()
        history = jax.block_until_ready(run(params))
        walls.append(time.perf_counter() - started)
    assert bool(np.all(history.converged)), "a jaxtube step did not converge"
    return np.asarray(history.time), np.asarray(history.node_position[:, -1, 2]), \
        float(np.median(walls)), steps


def run_pyelastica(elements, duration, time_step):
    import elastica as ea

    class Simulator(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.CallBacks):
        pass

    area_inertia = np.pi * RADIUS**4 / 4
    youngs = STIFFNESS / area_inertia
    density = MASS / (np.pi * RADIUS**2)
    simulator = Simulator()
    rod = ea.CosseratRod.straight_rod(
        elements, np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 0, 1.0]), LENGTH, RADIUS,
        density, youngs_modulus=youngs, shear_modulus=2 * youngs)
    # A thin-walled section's rotary inertia (r^2 / 2 per unit mass), twice the solid one's.
    rod.mass_second_moment_of_inertia *= 2.0
    rod.inv_mass_second_moment_of_inertia /= 2.0
    simulator.append(rod)
    simulator.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,),
                                   constrained_director_idx=(0,))
    simulator.add_forcing_to(rod).using(ea.EndpointForces, np.zeros(3),
                                        np.array([0.0, 0, -TIP_LOAD]), ramp_up_time=1e-12)
    record = {"time": [], "tip": []}
    every = max(1, int(round(2e-4 / time_step)))

    class Recorder(ea.CallBackBaseClass):
        def make_callback(self, system, time, current_step):
            if current_step % every == 0:
                record["time"].append(time)
                record["tip"].append(system.position_collection[2, -1])

    simulator.collect_diagnostics(rod).using(Recorder)
    simulator.finalize()
    steps = int(round(duration / time_step))
    started = time.perf_counter()
    ea.integrate(ea.PositionVerlet(), simulator, duration, steps, progress_bar=False)
    return (np.asarray(record["time"]), np.asarray(record["tip"]),
            time.perf_counter() - started, steps)


def convergence(reference):
    """The tables the resolutions rest on: jaxtube's modal frequency against the segment
    count and the rule's period elongation against the steps per period; PyElastica's
    response frequency (1 s) against the element count at its largest stable step."""
    print("jaxtube modal first frequency against the Rayleigh beam:")
    for segments in (8, 16, 32):
        structure, params, static = cantilever(segments)
        first = float(jt.modes(structure, params, static, count=1).frequency[0])
        print(f"  {segments:3d} segments: {first:.4f} Hz ({100 * (first / reference - 1):+.2f} %)")
    print("average-acceleration period elongation (frequency error) against steps per period:")
    for per_period in (20, 30, 35, 40):
        wh = 2 * np.pi / per_period
        print(f"  {per_period:3d}: {100 * (2 * np.arctan(wh / 2) / wh - 1):+.2f} %")
    print("PyElastica response first frequency (1 s) against the element count:")
    for elements, step in ((50, 1e-5), (100, 5e-6), (200, 4e-6)):
        t, z, wall, _ = run_pyelastica(elements, 1.0, step)
        f, _ = tip_frequency_and_amplitude(t, z)
        print(f"  {elements:3d} elements, {1e6 * step:.1f} us: {f:.4f} Hz "
              f"({100 * (f / reference - 1):+.2f} %), {wall:.1f} s wall")


def kite_real_time(duration=1.0, crown_load=20.0, steps_per_period=20):
    """The tube kite of ``experiments/tube_kite.py`` with six struts (56 + 6 x 14 = 140
    segments; struts 0.15 kg/m), tips clamped, under self-weight, then a sudden crown load
    ``crown_load`` [N] downwards for ``duration`` [s], ``steps_per_period`` steps a period of
    its first mode: the real-time factor (simulated seconds per wall second, warm)."""
    from experiments.tube_kite import build_kite

    model = build_kite(56, 6, strut_mass_per_length=0.15)
    structure, params = model.build()
    static = jt.equilibrium(structure, params)
    first = float(jt.modes(structure, params, static, count=1).frequency[0])
    step = 1.0 / (steps_per_period * first)
    steps = int(round(duration / step))
    load = jt.dynamic_load(structure, params, {model.node("le:centre"): [0.0, 0.0, -crown_load]},
                           jt.StepFunction())
    run = jax.jit(lambda p: jt.simulate_dynamics(structure, p, step, steps, initial=static,
                                                 loads=(load,)))
    started = time.perf_counter()
    jax.block_until_ready(run(params))
    compile_s = time.perf_counter() - started
    walls = []
    for _ in range(3):
        started = time.perf_counter()
        history = jax.block_until_ready(run(params))
        walls.append(time.perf_counter() - started)
    wall = float(np.median(walls))
    crown = structure.node_id(model.node("le:centre"))
    drop = float(static.node_position[crown, 2] - np.min(history.node_position[:, crown, 2]))
    print(f"tube kite: {structure.segment_count} segments, first mode {first:.3f} Hz, {steps} "
          f"steps of {1e3 * step:.2f} ms, all converged: {bool(np.all(history.converged))}, "
          f"{float(np.mean(history.iterations)):.2f} Newton iterations a step; crown drops "
          f"{1e3 * drop:.1f} mm at most; first call {compile_s:.1f} s")
    print(f"real-time factor: {duration / wall:.2f} ({duration} s simulated in {wall:.3f} s "
          f"wall, median of 3, warm; {1e3 * wall / steps:.2f} ms a step)")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="0.25 s simulated, one repeat")
    parser.add_argument("--convergence", action="store_true",
                        help="print the resolution tables instead of the comparison")
    parser.add_argument("--kite", action="store_true",
                        help="the tube kite's real-time factor instead of the comparison")
    args = parser.parse_args()
    if args.kite:
        return kite_real_time()
    reference = rayleigh_beam_frequency()
    beam = 1.8751**2 * np.sqrt(STIFFNESS / (MASS * LENGTH**4)) / (2 * np.pi)
    static = TIP_LOAD * LENGTH**3 / (3 * STIFFNESS)
    print(f"reference: Rayleigh beam first mode {reference:.4f} Hz (Euler-Bernoulli {beam:.4f}"
          f" Hz); static tip deflection {1e3 * static:.3f} mm (a step load swings about it "
          "with about that amplitude)")
    if args.convergence:
        run_pyelastica(20, 1e-4, 4e-6)  # numba compilation
        return convergence(reference)
    duration = 0.25 if args.quick else 1.0
    t, z, wall_j, steps_j = run_jaxtube(SEGMENTS, STEPS_PER_PERIOD, duration,
                                        1 if args.quick else 3)
    f_j, a_j = tip_frequency_and_amplitude(t, z)
    print(f"jaxtube   {SEGMENTS} segments, {steps_j} steps: {f_j:.4f} Hz "
          f"({100 * (f_j / reference - 1):+.2f} %), amplitude {1e3 * a_j:.4f} mm, "
          f"{wall_j:.3f} s wall (median, warm)")
    run_pyelastica(20, 1e-4, 4e-6)  # numba compilation
    t, z, wall_e, steps_e = run_pyelastica(ELEMENTS, duration, ELASTICA_STEP)
    f_e, a_e = tip_frequency_and_amplitude(t, z)
    print(f"PyElastica {ELEMENTS} elements, {steps_e} steps: {f_e:.4f} Hz "
          f"({100 * (f_e / reference - 1):+.2f} %), amplitude {1e3 * a_e:.4f} mm, "
          f"{wall_e:.3f} s wall")
    print(f"agreement: first-mode frequency {100 * (f_j / f_e - 1):+.2f} %, amplitude "
          f"{100 * (a_j / a_e - 1):+.2f} %; jaxtube {wall_e / wall_j:.1f}x faster "
          f"(PyElastica wall / jaxtube wall, {duration} s simulated)")


if __name__ == "__main__":
    main()
