"""Benchmark: a 1 m, r = 75 mm cantilever on a linear law under a sudden tip load, 1 s,
jaxtube (implicit Newmark on SO(3), rigid segments) against PyElastica (explicit
position Verlet, Cosserat rod), side by side in one process.

Both models have the same bending stiffness EI and mass per length; PyElastica's rod is
solid (its E from EI and its shear modulus high, so that it bends as Euler-Bernoulli), and
its rotary inertia is a solid section's (negligible here). Its explicit step must resolve
the fastest (shear) wave in the finest element: 4 us for 50 elements. Compared: the first-mode
frequency of the tip history (zero crossings about the mean) and its amplitude (half the
peak-to-peak swing), against each other and against Euler-Bernoulli; wall times (jaxtube
warm: compiled before timing; PyElastica after a short warm-up run for numba). The last
line states the agreement and the wall-time ratio.

Run: ``python -m experiments.bench_dynamics [--quick]`` (needs the ``bench`` extra:
``pip install pyelastica``).
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


def tip_frequency_and_amplitude(time_s, tip_z):
    """Mean frequency from upward zero crossings about the mean [Hz], and half the
    peak-to-peak swing [m]."""
    swing = tip_z - 0.5 * (tip_z.max() + tip_z.min())
    up = np.flatnonzero((swing[:-1] < 0) & (swing[1:] >= 0))
    crossing = time_s[up] - swing[up] / (swing[up + 1] - swing[up]) * (time_s[1] - time_s[0])
    return (len(crossing) - 1) / (crossing[-1] - crossing[0]), 0.5 * np.ptp(tip_z)


def run_jaxtube(segments, steps_per_period, duration, repeats):
    structure, params = jt.cantilever(LENGTH, RADIUS, 2e4, segments, jt.LinearLaw(STIFFNESS),
                                      jt.LinearLaw(STIFFNESS / 1.3), mass_per_length=MASS)
    params = eqx.tree_at(lambda p: p.gravity, params, jnp.zeros(3))
    static = jt.equilibrium(structure, params)
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


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="0.25 s simulated, one repeat")
    args = parser.parse_args()
    duration = 0.25 if args.quick else 1.0
    beam = 1.8751**2 * np.sqrt(STIFFNESS / (MASS * LENGTH**4)) / (2 * np.pi)
    static = TIP_LOAD * LENGTH**3 / (3 * STIFFNESS)
    print(f"Euler-Bernoulli: first mode {beam:.4f} Hz; static tip deflection {1e3 * static:.3f}"
          " mm (a step load swings about it with that amplitude)")
    t, z, wall_j, steps_j = run_jaxtube(16, 40, duration, 1 if args.quick else 3)
    f_j, a_j = tip_frequency_and_amplitude(t, z)
    print(f"jaxtube   16 segments, {steps_j} steps: {f_j:.4f} Hz, amplitude {1e3 * a_j:.4f} mm,"
          f" {wall_j:.3f} s wall (median, warm)")
    run_pyelastica(20, 1e-4, 4e-6)  # numba compilation
    t, z, wall_e, steps_e = run_pyelastica(50, duration, 4e-6)
    f_e, a_e = tip_frequency_and_amplitude(t, z)
    print(f"PyElastica 50 elements, {steps_e} steps: {f_e:.4f} Hz, amplitude "
          f"{1e3 * a_e:.4f} mm, {wall_e:.3f} s wall")
    print(f"agreement: first-mode frequency {100 * (f_j / f_e - 1):+.2f} %, amplitude "
          f"{100 * (a_j / a_e - 1):+.2f} %; jaxtube {wall_e / wall_j:.1f}x faster "
          f"(PyElastica wall / jaxtube wall, {duration} s simulated)")


if __name__ == "__main__":
    main()
