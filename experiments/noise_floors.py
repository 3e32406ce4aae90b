"""Generating noise floors of the bundled datasets made before issue 16.

The floor of a dataset is the RMSE of its noise-free truth, evaluated at the recorded (noisy)
deflections, against the recorded forces: the smallest RMSE a model that predicts force at
the measured deflection can reach, and the number a noise estimate is to be judged against.
Writes ``tests/data/noise_floors.json``.

- ``tests/data/cantilever_shear.csv`` (made outside the project; its noise draws are not
  known): the truth rebuilt with the continuum solver, a tension-field tube with
  ``E t = 150 kN/m`` and Fichter shear ``G t = 5 kN/m``, ``k = 0.5``
  (``tests/data/README.md``), in displacement control at the recorded deflections.
- The datasets of ``experiments/make_effect_data.py`` and
  ``experiments/make_calibration_data.py``: their noise draws are replayed
  (``numpy.random.default_rng(seed)``, per curve the deflection draws then the force draws,
  as ``write_noisy_curves`` makes them). The loads are evenly spaced, ``P_k = P_max k / n``,
  so the recorded forces give each curve's ``P_max`` and the force noise's standard deviation
  by linear least squares (exact up to the 0.1 mN rounding: checked), and the noise-free
  points ``(u_k, P_k)`` follow. The truth at a recorded deflection is the cubic spline
  through the noise-free points of its curve (the recorded deflections lie within 0.2 mm of
  them; the spline's error there is far below the rounding).

    python -m experiments.noise_floors
"""

from __future__ import annotations

import json
import math
import pathlib
import time

import numpy as np
from scipy.interpolate import CubicSpline

from fitting import continuum, load_measurements

ROOT = pathlib.Path(__file__).resolve().parent.parent

#: (file, seed, deflection noise [mm]) of the replayed datasets.
REPLAYED = (
    ("tests/data/effects/none.csv", 101), ("tests/data/effects/none_one_radius.csv", 102),
    ("tests/data/effects/shear.csv", 103), ("tests/data/effects/reinforcement.csv", 104),
    ("tests/data/effects/clamp_compliance.csv", 105),
    ("tests/data/effects/self_weight.csv", 106), ("jaxtube/data/demo_hidden_effect.csv", 107),
    ("tests/data/effects/tip_mass.csv", 108), ("tests/data/calibration_spline.csv", 7))
NOISE_DEFLECTION_MM = 0.05


def replayed_floor(path: str, seed: int) -> float:
    data = load_measurements(ROOT / path)
    rng = np.random.default_rng(seed)
    draws = [(rng.standard_normal(c.point_count), rng.standard_normal(c.point_count))
             for c in data]
    # Recorded force = P_max,c k / n + sigma_F eps: unknowns P_max per curve and sigma_F.
    rows, target = [], []
    for c, (curve, (_, eps_force)) in enumerate(zip(data, draws)):
        n = curve.point_count
        for k in range(n):
            row = np.zeros(len(data) + 1)
            row[c], row[-1] = (k + 1) / n, eps_force[k]
            rows.append(row)
            target.append(curve.force[k])
    solution, *_ = np.linalg.lstsq(np.array(rows), np.array(target), rcond=None)
    misfit = float(np.max(np.abs(np.array(rows) @ solution - np.array(target))))
    if misfit > 2e-4:  # the replay does not match the file: refuse, do not guess
        raise RuntimeError(f"{path}: replayed noise does not reproduce the file ({misfit} N)")
    squares = []
    for c, (curve, (eps_deflection, _)) in enumerate(zip(data, draws)):
        n = curve.point_count
        loads = solution[c] * np.arange(1, n + 1) / n
        true_deflection = curve.deflection - NOISE_DEFLECTION_MM * 1e-3 * eps_deflection
        truth = CubicSpline(np.concatenate([[0.0], true_deflection]),
                            np.concatenate([[0.0], loads]))
        squares.extend((truth(curve.deflection) - curve.force) ** 2)
    return math.sqrt(float(np.mean(squares)))


def shared_shear_floor() -> float:
    squares = []
    for curve in load_measurements(ROOT / "tests/data/cantilever_shear.csv"):
        model = continuum.tension_field_cantilever(
            curve.pressure / continuum.BAR, curve.radius, curve.length, 150e3,
            shear_modulus=5e3, shear_factor=0.5)
        squares.extend((model.curve(np.asarray(curve.deflection)) - curve.force) ** 2)
    return math.sqrt(float(np.mean(squares)))


def main() -> None:
    out = {}
    for path, seed in REPLAYED:
        out[path] = replayed_floor(path, seed)
        print(f"{path}: {out[path]:.4f} N", flush=True)
    start = time.perf_counter()
    out["tests/data/cantilever_shear.csv"] = shared_shear_floor()
    print(f"tests/data/cantilever_shear.csv: {out['tests/data/cantilever_shear.csv']:.4f} N "
          f"({time.perf_counter() - start:.0f} s)", flush=True)
    target = ROOT / "tests" / "data" / "noise_floors.json"
    target.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
