"""Random designs of the diagnosis study and their data, made by the independent continuum
solver (:mod:`fitting.continuum`, which does not import jaxtube).

A design is a set of specimens ``(p [bar], r [m], L [m])``, points per curve, noise, and a
hidden truth: the tension-field tube of Comer & Levy (``E t = 150 kN/m``, as in
``experiments/make_hidden_effect_designs.py``) with none, one or two physical effects
switched on. Each curve runs to 85 % of the Comer-Levy collapse load (less the root moment
of any self-weight), at evenly spaced deflections.

Effect sizes are drawn log-uniformly from barely detectable to large, inside each effect's
plausible range (:attr:`fitting.EffectParameter.plausible`), in the units of the
diagnosis' parameter (:data:`SIZE_RANGES`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .. import continuum

#: Membrane stiffness of the tension-field truth, ``E t`` [N/m].
WALL_MODULUS = 150e3
#: Curves run to this fraction of the Comer-Levy collapse load.
LOAD_FRACTION = 0.85
#: Fichter shear factor ``k`` of the truth (flexibility ``u = 1 / (2 pi k G t)``).
SHEAR_FACTOR = 0.5
#: Log-uniform ranges of the hidden effects' sizes, in the diagnosis' parameters: shear
#: flexibility [m/N], reinforcement ``EI_r`` [N m^2], clamp compliance [rad/(N m)],
#: self-weight [kg/m]; each inside the parameter's plausible range.
SIZE_RANGES = {"shear": (3e-6, 3e-4), "reinforcement": (0.5, 80.0),
               "clamp_compliance": (1e-5, 1e-3), "self_weight": (0.02, 1.0)}
PHYSICAL_EFFECTS = tuple(SIZE_RANGES)
#: The specimen quantities each physical effect needs varied to be told apart from the
#: law's own pressure and radius scaling (:attr:`fitting.Effect.separated_by`), with the
#: number of distinct values each needs. Shear and clamp compliance each add a tip compliance
#: that grows with the length (``L`` and ``L^2``) beside the bending's ``L^3``: at two lengths
#: the bending stiffness and either compliance fit both slopes exactly (the other compliance
#: shows only as a constant shift of ``1 / EI``), so telling them from each other, as the
#: study's "found with no other effect named" asks, takes three lengths.
SEPARATED_BY = {"shear": {"length": 3, "pressure": 2},
                "reinforcement": {"pressure": 2, "radius": 2},
                "clamp_compliance": {"length": 3},
                "self_weight": {"length": 2, "pressure": 2}}
#: A quantity varies when its largest value exceeds its smallest by more than this ratio.
VARIED_RATIO = 1.2
PRESSURES_BAR = (0.15, 0.2, 0.25, 0.3, 0.35)
RADII_M = (0.05, 0.075, 0.1)
LENGTHS_M = (0.6, 0.8, 1.0, 1.2)


@dataclasses.dataclass(frozen=True)
class StudyDesign:
    """One design: ``index`` and ``seed`` (of its noise), the ``specimens`` ``(p [bar],
    r [m], L [m])``, ``points`` per curve, noise sd on force [N] and deflection [mm], and
    ``hidden``: ``(effect, size)`` pairs (empty: nothing hidden)."""

    index: int
    seed: int
    specimens: tuple[tuple[float, float, float], ...]
    points: int
    noise_force_N: float
    noise_deflection_mm: float
    hidden: tuple[tuple[str, float], ...] = ()

    @property
    def name(self) -> str:
        return f"design_{self.seed}_{self.index:04d}"

    @property
    def hidden_label(self) -> str:
        """``none`` or the hidden effects joined by ``+`` (sorted)."""
        return "+".join(sorted(name for name, _ in self.hidden)) or "none"

    def to_json(self) -> dict:
        return {"index": self.index, "seed": self.seed,
                "specimens": [list(s) for s in self.specimens], "points": self.points,
                "noise_force_N": self.noise_force_N,
                "noise_deflection_mm": self.noise_deflection_mm,
                "hidden": {name: size for name, size in self.hidden}}

    def separable(self, effect: str) -> bool:
        """Whether every quantity that tells ``effect`` apart (:data:`SEPARATED_BY`) varies
        (by more than :data:`VARIED_RATIO`) over at least the number of distinct values it
        needs."""
        columns = {"pressure": 0, "radius": 1, "length": 2}
        for quantity, needed in SEPARATED_BY[effect].items():
            values = {s[columns[quantity]] for s in self.specimens}
            if len(values) < needed or max(values) / min(values) <= VARIED_RATIO:
                return False
        return True


def draw_design(index: int, seed: int, small: bool = False) -> StudyDesign:
    """Design ``index`` of the study drawn with ``seed`` (the same pair gives the same design).

    Hidden: nothing (30 %), one physical effect (50 %) or two (20 %), sizes log-uniform in
    :data:`SIZE_RANGES`. Setup: 3, 4 or 6 curves (``small``: 3 or 4) over 1-3 pressures,
    radii and lengths, 8, 10 or 14 points per curve (``small``: 8), force noise log-uniform
    in 0.05-0.3 N, deflection noise uniform in 0.02-0.15 mm."""
    rng = np.random.default_rng([seed, index])
    draw = rng.random()
    count = 0 if draw < 0.3 else 1 if draw < 0.8 else 2
    effects = rng.choice(PHYSICAL_EFFECTS, size=count, replace=False)
    hidden = tuple((str(name), float(math.exp(rng.uniform(*np.log(SIZE_RANGES[name])))))
                   for name in sorted(effects))
    curves = int(rng.choice((3, 4) if small else (3, 4, 6)))
    points = 8 if small else int(rng.choice((8, 10, 14)))
    values = [sorted(rng.choice(options, size=int(rng.integers(1, 4)), replace=False).tolist())
              for options in (PRESSURES_BAR, RADII_M, LENGTHS_M)]
    grid = [(p, r, L) for p in values[0] for r in values[1] for L in values[2]]
    order = rng.permutation(len(grid))
    specimens = tuple(grid[order[k % len(grid)]] for k in range(curves))
    return StudyDesign(index=index, seed=seed, specimens=specimens, points=points,
                       noise_force_N=float(math.exp(rng.uniform(math.log(0.05), math.log(0.3)))),
                       noise_deflection_mm=float(rng.uniform(0.02, 0.15)), hidden=hidden)


def truth_model(p_bar: float, radius: float, length: float, hidden) -> continuum.CantileverModel:
    """The continuum truth of one specimen with the ``(effect, size)`` pairs of ``hidden``."""
    sizes = dict(hidden)
    fields = {}
    if "reinforcement" in sizes:
        fields["reinforcement_stiffness"] = sizes["reinforcement"]
    if "clamp_compliance" in sizes:
        fields["clamp_stiffness"] = 1.0 / sizes["clamp_compliance"]
    if "self_weight" in sizes:
        fields["mass_per_length"] = sizes["self_weight"]
    shear_modulus = (1.0 / (2.0 * math.pi * SHEAR_FACTOR * sizes["shear"])
                     if "shear" in sizes else None)
    return continuum.tension_field_cantilever(p_bar, radius, length, WALL_MODULUS,
                                              shear_modulus=shear_modulus,
                                              shear_factor=SHEAR_FACTOR, **fields)


@dataclasses.dataclass(frozen=True)
class DesignData:
    """A design's measured rows (the format of :func:`fitting.load_measurements`), its noise
    floor [N] (the noise-free truth at the recorded deflections against the recorded forces:
    the smallest RMSE a model of force at measured deflection can reach), and per hidden
    effect its signal-to-noise ratio: the largest ``|F with it - F without it|`` over the
    design's points in units of the noise floor (the force noise with the deflection noise
    carried through the curves' slopes)."""

    rows: list[dict]
    noise_floor_N: float
    snr: dict[str, float]


def _forces_where_reached(model, deflections_m: np.ndarray) -> np.ndarray:
    """``model.curve`` at ``deflections_m``; points the model cannot reach are nan."""
    try:
        return model.curve(deflections_m)
    except (continuum.DeflectionOutOfReach, RuntimeError):
        out = np.full(deflections_m.shape, np.nan)
        for k, deflection in enumerate(deflections_m):
            try:
                out[k] = model.tip_force(float(deflection))
            except (continuum.DeflectionOutOfReach, RuntimeError):
                break
        return out


def make_design_data(design: StudyDesign, path=None, with_snr: bool = True) -> DesignData:
    """The design's noisy curves (written as CSV to ``path`` when given), noise floor and
    effect signal-to-noise ratios (:class:`DesignData`; empty unless ``with_snr``: they cost
    a second solve of every curve per hidden effect)."""
    specs, truths = [], []
    sizes = dict(design.hidden)
    for p_bar, radius, length in design.specimens:
        model = truth_model(p_bar, radius, length, design.hidden)
        weight_moment = sizes.get("self_weight", 0.0) * continuum.GRAVITY * length**2 / 2
        collapse = continuum.comer_levy_collapse_load(p_bar * continuum.BAR, radius, length)
        max_load = LOAD_FRACTION * (collapse - weight_moment / length)
        deflections = continuum.prescribed_deflections(model, max_load, design.points)
        name = f"p{p_bar:g}-r{radius * 1e3:g}-L{length:g}"
        name += f"-{sum(s == (p_bar, radius, length) for s in design.specimens[:len(specs)])}"
        specs.append(continuum.CurveSpec(name, model, deflections, p_bar, radius))
        truths.append((p_bar, radius, length, deflections))
    rows = continuum.make_dataset(specs, design.noise_force_N, design.noise_deflection_mm,
                                  design.seed * 100003 + design.index, path)
    floor = continuum.noise_floor(specs, rows)
    snr = {}
    for effect, _ in design.hidden if with_snr else ():
        others = tuple(pair for pair in design.hidden if pair[0] != effect)
        largest = 0.0
        for spec, (p_bar, radius, length, deflections) in zip(specs, truths):
            at = np.asarray(deflections) * 1e-3
            with_it = spec.model.curve(at)
            without = _forces_where_reached(truth_model(p_bar, radius, length, others), at)
            gap = np.abs(with_it - without)
            if np.any(np.isfinite(gap)):
                largest = max(largest, float(np.nanmax(gap)))
        snr[effect] = largest / floor
    return DesignData(rows=rows, noise_floor_N=floor, snr=snr)
