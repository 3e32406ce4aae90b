"""Dynamics in ``jaxtube simulate`` (a spec with a ``[dynamics]`` table).

From rest at the static equilibrium under gravity, the ``[[load]]`` forces act with the
table's ``load_history`` (step, ramp or harmonic) for ``duration_s`` in steps of
``time_step_s`` (:func:`jaxtube.simulate_dynamics`). Writes into ``--out``:

- ``history.csv``: one row per step: ``step``, ``time_s``, ``load_factor``, the path node's
  displacement ``node_dx_mm``, ``node_dy_mm``, ``node_dz_mm``, ``kinetic_energy_J``,
  ``potential_energy_J``, ``converged`` (1/0), ``iterations``, ``residual``;
- ``history.png``: the path node's displacement and the energies against time;
- ``response.gif``: an animation of the deformed structure (at most 60 frames);
- ``modes.csv`` (as ``jaxtube modes``) at the static equilibrium, and ``summary.json``.

Exit code 1 when a step did not converge (the files are written, with those steps marked).
"""

from __future__ import annotations

import csv
import json
import sys
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.animation import FuncAnimation, PillowWriter  # noqa: E402

import jaxtube as jt  # noqa: E402

from .._data.units import MM_PER_M  # noqa: E402
from .common import write_directory  # noqa: E402
from .modes import MODE_COLUMNS, mode_rows  # noqa: E402

HISTORY_COLUMNS = ("step", "time_s", "load_factor", "node_dx_mm", "node_dy_mm", "node_dz_mm",
                   "kinetic_energy_J", "potential_energy_J", "converged", "iterations",
                   "residual")
GIF_FRAMES = 60


def _time_function(dynamics):
    if dynamics.load_history == "ramp":
        return jt.RampFunction(0.0, dynamics.ramp)
    if dynamics.load_history == "harmonic":
        return jt.HarmonicFunction(dynamics.frequency)
    return jt.StepFunction(0.0)


def simulate_spec_dynamics(spec: jt.LoadedSpec, out: Path, quiet: bool = False) -> int:
    """Run the ``[dynamics]`` table of a loaded spec and write the outputs into ``out``;
    returns the exit code (module docstring)."""
    started = time.perf_counter()
    structure, params, _, meta = spec
    dynamics = meta.dynamics
    say = (lambda message: None) if quiet else (
        lambda message: print(message, file=sys.stderr, flush=True))
    unloaded = eqx.tree_at(lambda p: p.node_force, params, jnp.zeros_like(params.node_force))
    static = jt.equilibrium(structure, unloaded)
    modes = jt.modes(structure, unloaded, static,
                     count=min(dynamics.modes, int(jax.flatten_util.ravel_pytree(
                         static.state)[0].shape[0])))
    time_function = _time_function(dynamics)
    load = jt.DynamicLoad(node_force=params.node_force, time_function=time_function)
    damping = jt.Damping(dynamics.mass_damping, dynamics.stiffness_damping)
    say(f"simulating {dynamics.duration} s in {dynamics.steps} steps of "
        f"{dynamics.time_step} s ...")
    history = jax.block_until_ready(jt.simulate_dynamics(
        structure, unloaded, dynamics.time_step, dynamics.steps, initial=static,
        loads=(load,), damping=damping))
    wall = time.perf_counter() - started
    node = meta.control_node
    motion = (np.asarray(history.node_position[:, node])
              - np.asarray(static.node_position[node])) * MM_PER_M
    times = np.asarray(history.time)
    factor = np.asarray(time_function(history.time))
    converged = np.asarray(history.converged)
    rows = [{"step": k + 1, "time_s": f"{times[k]:.9g}", "load_factor": f"{factor[k]:.6g}",
             "node_dx_mm": f"{motion[k, 0]:.6g}", "node_dy_mm": f"{motion[k, 1]:.6g}",
             "node_dz_mm": f"{motion[k, 2]:.6g}",
             "kinetic_energy_J": f"{float(history.kinetic_energy[k]):.9g}",
             "potential_energy_J": f"{float(history.potential_energy[k]):.9g}",
             "converged": int(converged[k]), "iterations": int(history.iterations[k]),
             "residual": f"{float(history.residual[k]):.3g}"} for k in range(len(times))]
    failed = np.flatnonzero(~converged)
    if failed.size:
        print(f"error: {failed.size} of {converged.size} steps did not converge (first: step "
              f"{failed[0] + 1} at t = {times[failed[0]]:.4g} s)", file=sys.stderr)
    history_figure = _history_figure(times, motion, history, meta.control_node_ref)
    summary = {"source": meta.source, "name": meta.name, "time_step_s": dynamics.time_step,
               "duration_s": dynamics.duration, "steps": dynamics.steps,
               "converged_steps": int(converged.sum()),
               "failed_steps": [int(k) + 1 for k in failed],
               "frequency_Hz": [float(f) for f in np.asarray(modes.frequency)],
               "peak_node_displacement_mm": float(np.abs(motion).max()),
               "wall_seconds": round(wall, 3),
               "real_time_factor": round(dynamics.duration / wall, 4)}

    def write_rows(columns, table):
        def write(path):
            with open(path, "w", newline="") as file:
                writer = csv.DictWriter(file, fieldnames=columns)
                writer.writeheader()
                writer.writerows(table)
        return write

    def write_summary(path):
        with open(path, "w") as file:
            json.dump(summary, file, indent=2, allow_nan=False)
            file.write("\n")

    write_directory(out, {
        "history.csv": write_rows(HISTORY_COLUMNS, rows),
        "history.png": lambda path: history_figure.savefig(path, dpi=120),
        "response.gif": lambda path: _animation(structure, history, times, path),
        "modes.csv": write_rows(MODE_COLUMNS, mode_rows(modes)),
        "summary.json": write_summary,
    })
    plt.close(history_figure)
    say(f"{converged.sum()} of {converged.size} steps converged; peak displacement of "
        f"{meta.control_node_ref} {summary['peak_node_displacement_mm']:.4g} mm; "
        f"{wall:.3g} s wall; wrote history.csv, history.png, response.gif, modes.csv, "
        f"summary.json to {out}")
    return 0 if failed.size == 0 else 1


def _history_figure(times, motion, history, node_name):
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
    for k, axis in enumerate("xyz"):
        top.plot(times, motion[:, k], label=f"d{axis}")
    top.set_ylabel(f"{node_name} displacement [mm]")
    top.legend(fontsize=8)
    kinetic = np.asarray(history.kinetic_energy)
    potential = np.asarray(history.potential_energy)
    bottom.plot(times, kinetic, label="kinetic")
    bottom.plot(times, potential - potential[0], label="potential - initial")
    bottom.plot(times, kinetic + potential - potential[0], label="sum")
    bottom.set_xlabel("time [s]")
    bottom.set_ylabel("energy [J]")
    bottom.legend(fontsize=8)
    figure.tight_layout()
    return figure


def _animation(structure, history, times, path):
    positions = np.asarray(history.node_position)
    frames = np.unique(np.linspace(0, len(times) - 1, min(GIF_FRAMES, len(times))).astype(int))
    figure = plt.figure(figsize=(4.5, 3.6))
    ax = figure.add_subplot(projection="3d")
    low, high = positions.min(axis=(0, 1)), positions.max(axis=(0, 1))
    pad = 0.5 * np.maximum(0.02 * float((high - low).max()) - (high - low), 0.0)
    low, high = low - pad, high + pad  # a planar motion keeps its flat axis visible
    ax.set_box_aspect(high - low)
    ax.set_xlim(low[0], high[0])
    ax.set_ylim(low[1], high[1])
    ax.set_zlim(low[2], high[2])
    tubes = [np.asarray(ids, dtype=int) for ids in structure.tube_node_ids] or [
        np.arange(positions.shape[1])]
    curves = [ax.plot(*positions[0, ids].T, "C0-")[0] for ids in tubes]
    label = ax.set_title("")

    def draw(frame):
        for curve, ids in zip(curves, tubes):
            curve.set_data_3d(*positions[frame, ids].T)
        label.set_text(f"t = {times[frame]:.3f} s")
        return curves

    FuncAnimation(figure, draw, frames=frames).save(path, writer=PillowWriter(fps=15),
                                                    dpi=70)
    plt.close(figure)
