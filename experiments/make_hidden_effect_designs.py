"""Hidden-effect datasets with a tension-field truth over several radii and pressures (issue 16).

Route (independent of jaxtube's rigid-segment solver and of the fitted spline model): the
continuum shooting solver :func:`fitting.continuum.tension_field_cantilever` (planar Reissner
elastica, the no-compression membrane tube of Comer & Levy, ``E t = 150 kN/m``) with one
effect switched on, evaluated in displacement control by
:func:`fitting.continuum.make_dataset`. The fitted model is the paper-form spline
``A (p r^3)^B``, which cannot follow this truth across radii (the tension-field tube's
wrinkling curvature ``p / (2 E t)`` does not depend on ``r``): ``radius_scaling`` is a right
answer wherever the radii differ.

Every dataset has 14 points per curve (6 curves, except the 4-curve control), at deflections
evenly spaced up to the deflection at 85 % of the Comer-Levy collapse load ``pi p r^3 / L``
(less the root moment of any self-weight). Noise: Gaussian, 0.15 N on force and 0.5 mm on
deflection for the issue's two designs, 0.2 mm on deflection for the others (whose short,
thick tubes are stiff: 0.5 mm there would be several newtons of force noise at small loads).
Each dataset's **noise floor** is the RMSE of the noise-free truth, evaluated at the noisy
(recorded) deflections, against the noisy forces: the smallest RMSE any model that predicts
force at the measured deflection can reach. It is written with the design to
``tests/data/effects/designs.json`` and in ``tests/data/effects/README.md``.

    python -m experiments.make_hidden_effect_designs               # all
    python -m experiments.make_hidden_effect_designs --only tf_shear
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

from fitting import continuum  # does not import jaxtube

ROOT = pathlib.Path(__file__).resolve().parent.parent

WALL_MODULUS = 150e3  # E t [N/m]
POINTS = 14
LOAD_FRACTION = 0.85
NOISE_FORCE_N = 0.15
TARGET = ROOT / "tests" / "data" / "effects"

TWO_BY_THREE = tuple((p, r, 1.0) for p in (0.15, 0.3) for r in (0.05, 0.075, 0.1))
MIXED = ((0.15, 0.05, 0.6), (0.3, 0.05, 1.2), (0.15, 0.075, 1.2), (0.3, 0.075, 0.8),
         (0.2, 0.1, 0.9), (0.2, 0.1, 1.2))
ONE_RADIUS = tuple((p, 0.075, L) for p in (0.15, 0.25, 0.35) for L in (0.8, 1.2))
FOUR_CURVES = tuple((p, r, 1.0) for p in (0.2, 0.3) for r in (0.05, 0.1))

# name: (specimens (p [bar], r [m], L [m]), hidden effect {CantileverModel field: value} or
# shear {"shear_modulus": G t}, seed, words, deflection noise [mm])
DESIGNS = {
    "tf_reinforcement": (TWO_BY_THREE, {"reinforcement_stiffness": 20.0}, 201,
                         "EI_r = 20 N m^2 (a taped seam); 2 pressures x 3 radii, L = 1 m "
                         "(the issue's failing design)", 0.5),
    "tf_clamp_compliance": (MIXED, {"clamp_stiffness": 3000.0}, 202,
                            "rotational clamp spring k = 3000 N m/rad (compliance 3.3e-4 "
                            "rad/(N m)); 3 radii, 3 pressures, 3 lengths", 0.2),
    "tf_self_weight": (MIXED, {"mass_per_length": 0.4}, 203,
                       "self-weight 0.4 kg/m; 3 radii, 3 pressures, 3 lengths", 0.2),
    "tf_shear": (MIXED, {"shear_modulus": 5e3}, 204,
                 "Fichter shear, G t = 5 kN/m, k = 0.5; 3 radii, 3 pressures, 3 lengths", 0.2),
    "tf_none_one_radius": (ONE_RADIUS, {}, 205,
                           "nothing hidden; one radius (75 mm), 3 pressures x 2 lengths", 0.2),
    "tf_none_four_curves": (FOUR_CURVES, {}, 206,
                            "nothing hidden; 2 pressures x 2 radii, L = 1 m (the issue's "
                            "4-curve control)", 0.5),
}


def truth(p_bar: float, radius: float, length: float, effect: dict):
    effect = dict(effect)
    shear_modulus = effect.pop("shear_modulus", None)
    return continuum.tension_field_cantilever(p_bar, radius, length, WALL_MODULUS,
                                              shear_modulus=shear_modulus, **effect)


def make(name: str) -> dict:
    specimens, effect, seed, words, noise_deflection_mm = DESIGNS[name]
    specs = []
    for p_bar, radius, length in specimens:
        model = truth(p_bar, radius, length, effect)
        weight_moment = effect.get("mass_per_length", 0.0) * continuum.GRAVITY * length**2 / 2
        collapse = continuum.comer_levy_collapse_load(p_bar * continuum.BAR, radius, length)
        max_load = LOAD_FRACTION * (collapse - weight_moment / length)
        deflections = continuum.prescribed_deflections(model, max_load, POINTS)
        specs.append(continuum.CurveSpec(f"p{p_bar:g}-r{radius * 1e3:g}-L{length:g}", model,
                                         deflections, p_bar, radius))
    path = TARGET / f"{name}.csv"
    rows = continuum.make_dataset(specs, NOISE_FORCE_N, noise_deflection_mm, seed, path)
    floor = continuum.noise_floor(specs, rows)
    return {"file": f"tests/data/effects/{name}.csv", "hidden": words,
            "effect": {k: v for k, v in effect.items()}, "seed": seed,
            "specimens": [list(s) for s in specimens], "points_per_curve": POINTS,
            "noise_force_N": NOISE_FORCE_N, "noise_deflection_mm": noise_deflection_mm,
            "noise_floor_N": floor}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=sorted(DESIGNS), nargs="+")
    names = parser.parse_args().only or list(DESIGNS)
    meta_path = TARGET / "designs.json"
    meta = json.loads(meta_path.read_text()) if meta_path.exists() else {}
    for name in names:
        start = time.perf_counter()
        meta[name] = make(name)
        print(f"{name}: floor {meta[name]['noise_floor_N']:.4f} N "
              f"({time.perf_counter() - start:.0f} s)", flush=True)
        meta_path.write_text(json.dumps(meta, indent=1) + "\n")


if __name__ == "__main__":
    main()
