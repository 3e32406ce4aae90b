"""Paper Fig. 4: the three-regime spline law, its pivot points and regimes.

The spline is :meth:`jaxtube.SplineLaw.from_tension_field` (nine pivots, three per regime)
through the tension-field tube of Comer & Levy (``E t = 150 kN/m``) at 0.2 bar and
r = 75 mm; the tension-field law itself is drawn for comparison, with the wrinkling moment
``pi p r^3 / 2`` and the collapse moment ``pi p r^3``. No measured data are involved.

    python -m experiments.fig4_spline_law [--quick] [--out FILE.png]
"""

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from experiments._synthetic import jt, parser, save

PRESSURE, RADIUS, WALL = 0.2e5, 0.075, 150e3


def main() -> None:
    args = parser("fig4_spline_law", __doc__.splitlines()[0]).parse_args()
    spline = jt.SplineLaw.from_tension_field(WALL, PRESSURE, RADIUS)
    tension = jt.TensionFieldLaw(WALL)
    curvatures, moments = (np.asarray(v) for v in spline.pivots(PRESSURE, RADIUS))
    kappa = np.geomspace(0.05 * curvatures[0], 1.5 * curvatures[-1], 200 if args.quick else 2000)
    figure, ax = plt.subplots(figsize=(8, 5), constrained_layout=True)
    bounds = np.concatenate([[kappa[0]], curvatures[[2, 5]], [kappa[-1]]])
    for k, (name, colour) in enumerate((("unwrinkled", "#dff0d8"), ("wrinkled", "#fcf8e3"),
                                        ("collapsed", "#f2dede"))):
        ax.axvspan(bounds[k], bounds[k + 1], color=colour, label=f"regime {k}: {name}")
    ax.plot(kappa, np.asarray(spline.moment(kappa, PRESSURE, RADIUS)), "k-", lw=2,
            label="spline law (9 pivots)")
    ax.plot(kappa, np.asarray(tension.moment(kappa, PRESSURE, RADIUS)), "C0--",
            label=f"tension-field tube, E t = {WALL / 1e3:g} kN/m")
    ax.plot(curvatures, moments, "o", color="C3", ms=7, label="pivot points")
    for level, text in ((0.5, "M_w = pi p r^3 / 2"), (1.0, "M_c = pi p r^3")):
        ax.axhline(level * math.pi * PRESSURE * RADIUS**3, color="grey", lw=0.8, ls=":")
        ax.annotate(text, (kappa[-1], level * math.pi * PRESSURE * RADIUS**3), ha="right",
                    va="bottom", fontsize=9, color="grey")
    ax.set_xscale("log")
    ax.set_xlim(kappa[0], kappa[-1])
    ax.set_xlabel("curvature kappa [1/m] (log scale)")
    ax.set_ylabel("bending moment M [N m]")
    ax.set_title(f"Three-regime spline law (Breukels & Ockels 2008, Fig. 4): "
                 f"{PRESSURE / 1e5:g} bar, r = {RADIUS * 1e3:g} mm")
    ax.legend(loc="upper left", fontsize=8)
    save(figure, args.out)


if __name__ == "__main__":
    main()
