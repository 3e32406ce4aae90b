"""The ``[dynamics]`` table: time step, duration, damping, air inertia and how the
``[[load]]`` forces act in time (docs/spec-format.md, "Dynamics")."""

from __future__ import annotations

import dataclasses

from .check import check_keys, read_number, read_string, read_table
from .context import SpecContext

LOAD_HISTORIES = ("step", "ramp", "harmonic")
DYNAMICS_KEYS = ("time_step_s", "duration_s", "load_history", "ramp_s", "frequency_Hz",
                 "mass_damping_per_s", "stiffness_damping_s", "air_temperature_K",
                 "added_mass_coefficient", "ambient_air_density_kg_per_m3", "modes")


@dataclasses.dataclass(frozen=True)
class DynamicsSpec:
    """A checked ``[dynamics]`` table (SI units).

    Attributes:
        time_step, duration: [s]. load_history: ``"step"``, ``"ramp"`` or ``"harmonic"``
            (how the ``[[load]]`` forces act from t = 0). ramp: rise time [s].
        frequency: of a harmonic load [Hz]. mass_damping: [1/s]. stiffness_damping: [s].
        air_temperature: enclosed air temperature [K] or ``None`` (air mass left out).
        added_mass_coefficient: ``C_a`` of the surrounding air. ambient_air_density:
            [kg/m^3]. modes: how many natural modes to report.
    """

    time_step: float
    duration: float
    load_history: str = "step"
    ramp: float = 0.0
    frequency: float = 0.0
    mass_damping: float = 0.0
    stiffness_damping: float = 0.0
    air_temperature: float | None = None
    added_mass_coefficient: float = 0.0
    ambient_air_density: float = 1.225
    modes: int = 10

    @property
    def steps(self) -> int:
        return max(1, int(round(self.duration / self.time_step)))


def read_dynamics(p, value, ctx: SpecContext) -> None:
    table = read_table(p, value, "dynamics")
    if table is None:
        return
    where = "dynamics"
    check_keys(p, table, where, DYNAMICS_KEYS,
               {"time_step_s": "the time step [s], a positive number",
                "duration_s": "the simulated time [s], a positive number"})
    step = read_number(p, table, "time_step_s", where, positive=True)
    duration = read_number(p, table, "duration_s", where, positive=True)
    history = read_string(p, table, "load_history", where, default="step",
                          choices=LOAD_HISTORIES)
    ramp = read_number(p, table, "ramp_s", where, default=None, positive=True)
    frequency = read_number(p, table, "frequency_Hz", where, default=None, positive=True)
    if history == "ramp" and ramp is None:
        p.add(f"{where}.ramp_s", "missing key (expected the rise time [s] of load_history "
              "= 'ramp', a positive number)")
    if history == "harmonic" and frequency is None:
        p.add(f"{where}.frequency_Hz", "missing key (expected the frequency [Hz] of "
              "load_history = 'harmonic', a positive number)")
    values = dict(
        mass_damping=read_number(p, table, "mass_damping_per_s", where, default=0.0,
                                 minimum=0.0),
        stiffness_damping=read_number(p, table, "stiffness_damping_s", where, default=0.0,
                                      minimum=0.0),
        air_temperature=read_number(p, table, "air_temperature_K", where, default=None,
                                    positive=True),
        added_mass_coefficient=read_number(p, table, "added_mass_coefficient", where,
                                           default=0.0, minimum=0.0),
        ambient_air_density=read_number(p, table, "ambient_air_density_kg_per_m3", where,
                                        default=1.225, positive=True),
        modes=read_number(p, table, "modes", where, default=10, positive=True, integer=True),
    )
    if None in (step, duration, history) or any(
            values[k] is None for k in values if k != "air_temperature"):
        return
    ctx.dynamics = DynamicsSpec(time_step=float(step), duration=float(duration),
                                load_history=history, ramp=float(ramp or 0.0),
                                frequency=float(frequency or 0.0), **values)
