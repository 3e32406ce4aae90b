"""Make the synthetic bench data of the calibration tests, by an independent route.

The "true" bending law is a three-regime :class:`jaxtube.SplineLaw` in the paper's form
(pivots ``(1, 1, 1)``, exponents ``B = 0.8`` for curvatures and ``1.1`` for moments, pivots
sampled from a tension-field tube with ``E t = 150 kN/m`` at 0.25 bar and r = 75 mm). Its
moment-curvature relation is handed to the continuum shooting solver
:class:`fitting.continuum.CantileverModel` (a planar inextensible elastica integrated with
scipy's ODE solver), which is a different formulation and solver from jaxtube's rigid-segment
chain. Curves: 1 m cantilevers at 0.15, 0.25 and 0.35 bar and radii 60 and 90 mm, 12 points
each at tip loads evenly spaced up to 85 % of the law's collapse load (collapse pivot moment
over L); Gaussian noise of 1.5 % of the largest force (force) and 0.05 mm (deflection),
seed 7.

    python -m experiments.make_calibration_data tests/data/calibration_spline.csv
"""

import csv
import sys

import jax
import numpy as np

import jaxtube as jt
from fitting import continuum

PAPER_LAW_EXPONENTS = (0.8, 1.1)
REFERENCE = (0.25e5, 0.075)
PRESSURES_BAR = (0.15, 0.25, 0.35)
RADII_M = (0.06, 0.09)
LENGTH_M = 1.0
POINTS = 12
NOISE_FRACTION = 0.015
NOISE_DEFLECTION_MM = 0.05
SEED = 7


def true_law() -> jt.SplineLaw:
    base = jt.SplineLaw.from_tension_field(150e3, *REFERENCE, form="paper",
                                           pivots_per_regime=(1, 1, 1))
    curvatures, moments = base.pivots(*REFERENCE)
    return jt.SplineLaw.from_pivots(curvatures, moments, *REFERENCE,
                                    curvature_exponent=PAPER_LAW_EXPONENTS[0],
                                    moment_exponent=PAPER_LAW_EXPONENTS[1],
                                    pivots_per_regime=(1, 1, 1))


def write_noisy_curves(path, curves, noise_force: float, rng) -> None:
    """Write ``(name, p_bar, radius_m, length_m, deflections_m [n], loads_N [n])`` curves as
    measurement CSV rows with Gaussian noise: per curve, ``NOISE_DEFLECTION_MM`` on the
    deflections, then ``noise_force`` [N] on the forces."""
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["curve", "setup", "pressure_bar", "radius_m", "length_m",
                         "deflection_mm", "force_N"])
        for name, p_bar, radius, length, deflections, loads in curves:
            u = deflections * 1e3 + NOISE_DEFLECTION_MM * rng.standard_normal(loads.size)
            f = loads + noise_force * rng.standard_normal(loads.size)
            for ui, fi in zip(u, f):
                writer.writerow([name, "cantilever_tip", f"{p_bar:g}", f"{radius:g}",
                                 f"{length:g}", f"{ui:.3f}", f"{fi:.4f}"])


def main(path: str) -> None:
    law = true_law()
    rng = np.random.default_rng(SEED)
    curves = []
    for radius in RADII_M:
        for p_bar in PRESSURES_BAR:
            pressure = p_bar * 1e5
            compiled = jax.jit(lambda kappa, p=pressure, r=radius: law.moment(kappa, p, r))

            def moment(kappa, compiled=compiled):
                return float(compiled(kappa))

            curvatures, moments = (np.asarray(v) for v in law.pivots(pressure, radius))
            model = continuum.CantileverModel(
                LENGTH_M, continuum.law_from_moment(moment, curvature_scale=curvatures[0]))
            collapse_load = moments[1] / LENGTH_M  # the collapse pivot's moment over L
            # Points on the curve by shooting at prescribed loads (force control is the
            # continuum solver's most robust mode; every point lies on the curve).
            loads = 0.85 * collapse_load * np.arange(1, POINTS + 1) / POINTS
            deflections = np.array([model.tip_deflection(load) for load in loads])
            name = f"p{p_bar:g}-r{radius * 1e3:g}"
            curves.append((name, p_bar, radius, deflections, loads))
            print(f"{name}: up to {deflections[-1] * 1e3:.1f} mm, {loads[-1]:.2f} N", flush=True)
    noise_force = NOISE_FRACTION * max(c[4][-1] for c in curves)
    write_noisy_curves(path, [(name, p_bar, radius, LENGTH_M, deflections, loads)
                              for name, p_bar, radius, deflections, loads in curves],
                       noise_force, rng)
    print(f"wrote {path}: force noise sd {noise_force:.4f} N, deflection noise sd "
          f"{NOISE_DEFLECTION_MM} mm")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "tests/data/calibration_spline.csv")
