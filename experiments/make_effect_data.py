"""Make synthetic cantilever datasets, each with one known hidden physical effect.

Route (independent of jaxtube's rigid-segment solver): the base bending law is
``true_law()`` of ``experiments/make_calibration_data.py`` (a paper-form
:class:`jaxtube.SplineLaw`, pivots ``(1, 1, 1)``); its jitted ``M(kappa, p, r)`` is handed to
:func:`fitting.continuum.law_from_moment` and the curves are computed by the continuum
shooting solver :class:`fitting.continuum.CantileverModel` (planar Reissner elastica, scipy
DOP853) under force control at prescribed tip loads. Each point's deflection is
``model.tip_deflection(load)``, measured from the unloaded (possibly self-weighted) shape.

Specimens ``(p [bar], r [m], L [m])``: default (0.15, 0.075, 0.6), (0.30, 0.075, 0.6),
(0.15, 0.075, 1.2), (0.30, 0.075, 1.2), (0.22, 0.06, 0.9), (0.22, 0.09, 0.9); one-radius
set: the same with the last two at r = 0.075 m and L = 0.9, 0.75 m. 14 points per curve at
loads evenly spaced from ``load_max / 14`` to ``load_max``, with
``load_max = 0.85 (M_c(p, r) - w g L^2 / 2 - m g L) / L``, ``M_c`` the law's collapse pivot
moment, ``w`` the mass per length (0 unless self-weight), ``m`` a tip mass (0 unless
tip_mass), g = 9.81 m/s^2. If the solver fails on a
dataset, its factor drops to 0.80 (reported).

Datasets (file: effect, seed):

- ``tests/data/effects/none.csv``: none, default specimens, seed 101.
- ``tests/data/effects/none_one_radius.csv``: none, one-radius specimens, seed 102.
- ``tests/data/effects/shear.csv``: Fichter shear, ``S = p pi r^2 + k G t 2 pi r`` with
  ``G t = 5e3 N/m``, ``k = 0.5`` (per specimen), seed 103.
- ``tests/data/effects/reinforcement.csv``: ``EI_r = 40 N m^2``, seed 104.
- ``tests/data/effects/clamp_compliance.csv``: ``k_clamp = 2500 N m/rad``, seed 105.
- ``tests/data/effects/self_weight.csv``: ``w = 0.8 kg/m``, seed 106.
- ``jaxtube/data/demo_hidden_effect.csv``: clamp compliance ``k_clamp = 1500 N m/rad``,
  default specimens, seed 107.
- ``tests/data/effects/tip_mass.csv``: a 0.5 kg point mass hanging at the tip (not a built-in
  effect: the user-effect example ``experiments/effects/tip_mass.py``); ``load_max`` is
  reduced by its root moment ``m g L``; default specimens, seed 108.

Noise: Gaussian, force sd 1 % of the dataset's largest noiseless force, deflection sd
0.05 mm (``numpy.random.default_rng(seed)``; per curve, deflection draws then force draws).
Rounded to 0.001 mm and 0.0001 N. Columns
``curve,setup,pressure_bar,radius_m,length_m,deflection_mm,force_N``; setup
``cantilever_tip``; curve names like ``p0.15-r75-L0.6``.

    python -m experiments.make_effect_data               # all datasets
    python -m experiments.make_effect_data --only shear  # one (name = file stem)
"""

import argparse
import importlib.util
import pathlib
import time

import jax
import numpy as np

from fitting import continuum

ROOT = pathlib.Path(__file__).resolve().parent.parent
_spec = importlib.util.spec_from_file_location(
    "make_calibration_data", ROOT / "experiments" / "make_calibration_data.py")
_calibration = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_calibration)
true_law = _calibration.true_law

GRAVITY = 9.81
POINTS = 14
LOAD_FACTOR, FALLBACK_FACTOR = 0.85, 0.80
NOISE_FRACTION = 0.01
NOISE_DEFLECTION_MM = _calibration.NOISE_DEFLECTION_MM  # the shared writer adds it
DEFAULT = ((0.15, 0.075, 0.6), (0.30, 0.075, 0.6), (0.15, 0.075, 1.2), (0.30, 0.075, 1.2),
           (0.22, 0.06, 0.9), (0.22, 0.09, 0.9))
ONE_RADIUS = DEFAULT[:4] + ((0.22, 0.075, 0.9), (0.22, 0.075, 0.75))


def shear(pressure, radius):
    return {"shear_stiffness": continuum.fichter_shear_stiffness(pressure, radius, 5e3, 0.5)}


# name: (path, specimens, effect(pressure [Pa], radius [m]) -> CantileverModel kwargs, seed)
DATASETS = {
    "none": ("tests/data/effects/none.csv", DEFAULT, lambda p, r: {}, 101),
    "none_one_radius": ("tests/data/effects/none_one_radius.csv", ONE_RADIUS,
                        lambda p, r: {}, 102),
    "shear": ("tests/data/effects/shear.csv", DEFAULT, shear, 103),
    "reinforcement": ("tests/data/effects/reinforcement.csv", DEFAULT,
                      lambda p, r: {"reinforcement_stiffness": 40.0}, 104),
    "clamp_compliance": ("tests/data/effects/clamp_compliance.csv", DEFAULT,
                         lambda p, r: {"clamp_stiffness": 2500.0}, 105),
    "self_weight": ("tests/data/effects/self_weight.csv", DEFAULT,
                    lambda p, r: {"mass_per_length": 0.8}, 106),
    "demo_hidden_effect": ("jaxtube/data/demo_hidden_effect.csv", DEFAULT,
                           lambda p, r: {"clamp_stiffness": 1500.0}, 107),
    # Not a built-in effect: the user-effect example (experiments/effects/tip_mass.py).
    "tip_mass": ("tests/data/effects/tip_mass.csv", DEFAULT, lambda p, r: {"tip_mass": 0.5},
                 108),
}
CHECKED = ("shear", "reinforcement", "clamp_compliance", "self_weight", "demo_hidden_effect",
           "tip_mass")

_LAW = true_law()
_LAWS = {}


def continuum_law(pressure, radius):
    """The base law at (p [Pa], r [m]) as a continuum BendingLaw, and its collapse moment."""
    if (pressure, radius) not in _LAWS:
        compiled = jax.jit(lambda kappa: _LAW.moment(kappa, pressure, radius))
        curvatures, moments = (np.asarray(v) for v in _LAW.pivots(pressure, radius))
        law = continuum.law_from_moment(lambda kappa: float(compiled(kappa)),
                                        curvature_scale=float(curvatures[0]))
        _LAWS[pressure, radius] = (law, float(moments[1]))
    return _LAWS[pressure, radius]


def make_curves(specimens, effect, factor):
    """Noiseless curves: (name, p_bar, r, L, loads [N], deflections [m], effect model)."""
    curves = []
    for p_bar, radius, length in specimens:
        pressure = p_bar * 1e5
        law, collapse_moment = continuum_law(pressure, radius)
        kwargs = effect(pressure, radius)
        model = continuum.CantileverModel(length, law, **kwargs)
        weight_moment = (kwargs.get("mass_per_length", 0.0) * GRAVITY * length**2 / 2
                         + kwargs.get("tip_mass", 0.0) * GRAVITY * length)
        load_max = factor * (collapse_moment - weight_moment) / length
        loads = load_max * np.arange(1, POINTS + 1) / POINTS
        deflections = np.array([model.tip_deflection(load) for load in loads])
        name = f"p{p_bar:g}-r{radius * 1e3:g}-L{length:g}"
        curves.append((name, p_bar, radius, length, loads, deflections, model))
    return curves


def make_dataset(name):
    path, specimens, effect, seed = DATASETS[name]
    factor = LOAD_FACTOR
    try:
        curves = make_curves(specimens, effect, factor)
    except RuntimeError as error:
        factor = FALLBACK_FACTOR
        print(f"{name}: solver failed at factor {LOAD_FACTOR} ({error}); using {factor}")
        curves = make_curves(specimens, effect, factor)
    rng = np.random.default_rng(seed)
    largest = max(c[4][-1] for c in curves)
    noise_force = NOISE_FRACTION * largest
    target = ROOT / path
    target.parent.mkdir(parents=True, exist_ok=True)
    _calibration.write_noisy_curves(
        target, [(curve, p_bar, radius, length, deflections, loads)
                 for curve, p_bar, radius, length, loads, deflections, _ in curves],
        noise_force, rng)
    print(f"{name}: wrote {path} (seed {seed}, load factor {factor}); largest force "
          f"{largest:.3f} N, force sd {noise_force:.4f} N, deflection sd "
          f"{NOISE_DEFLECTION_MM} mm", flush=True)
    if name in CHECKED:  # effect vs no effect at each specimen's largest load
        for curve, p_bar, radius, length, loads, deflections, _ in curves:
            law, _ = continuum_law(p_bar * 1e5, radius)
            plain = continuum.CantileverModel(length, law).tip_deflection(loads[-1])
            print(f"  {curve:16s} P {loads[-1]:7.3f} N: u {deflections[-1] * 1e3:8.2f} mm,"
                  f" no effect {plain * 1e3:8.2f} mm, rel diff "
                  f"{(deflections[-1] - plain) / plain:+.2%}", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=sorted(DATASETS), help="regenerate one dataset")
    only = parser.parse_args().only
    names = [only] if only else list(DATASETS)
    start = time.perf_counter()
    for name in names:
        make_dataset(name)
    print(f"done in {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
