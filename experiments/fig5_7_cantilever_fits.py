"""Paper Figs. 5 and 7: cantilever fits at 0.2 and 0.4 bar (1 m, r = 75 mm).

Measured-style data (the paper's measurements are not public): the bench curves come from
the independent continuum solver (``fitting.continuum``) with a known law, the spline of
``experiments/make_calibration_data.py`` (pivots from a tension-field tube, exponents
B = 0.8 and 1.1), plus 1.5 % force noise; then the default calibration (``fitting.fit``,
paper form, pivots 1,1,1) fits both curves at once. The figure shows each curve's points,
the fitted model with its 95 % band, and the true (noise-free) curve.

    python -m experiments.fig5_7_cantilever_fits [--quick] [--out FILE.png]
"""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from experiments._synthetic import QUICK_POINTS, continuum_curve, fit, measured, parser, save
from experiments.make_calibration_data import true_law

PRESSURES_BAR, RADIUS, LENGTH = (0.2, 0.4), 0.075, 1.0


def main() -> None:
    args = parser("fig5_7_cantilever_fits", __doc__.splitlines()[0]).parse_args()
    law = true_law()
    points = QUICK_POINTS if args.quick else 15
    curves = [(f"{p:g} bar", p, RADIUS, LENGTH,
               *continuum_curve(law, p * 1e5, RADIUS, LENGTH, points)) for p in PRESSURES_BAR]
    data = measured(curves)
    result = fit(data, args.quick)
    figure, axes = plt.subplots(1, 2, figsize=(11, 4.5), constrained_layout=True)
    for ax, curve, (name, _, _, _, true_u, true_f), model in zip(axes, data, curves,
                                                               result.force):
        ax.plot(true_u * 1e3, true_f, "k-", lw=1, label="true law (continuum solver)")
        ax.plot(curve.deflection * 1e3, curve.force, "o", ms=4, label="bench-style data")
        order = np.argsort(curve.deflection)
        ax.plot(curve.deflection[order] * 1e3, model[order], "C3-", label="fitted model")
        ax.set_title(f"{name}, L = {LENGTH:g} m, r = {RADIUS * 1e3:g} mm")
        ax.set_xlabel("tip deflection [mm]")
        ax.set_ylabel("tip load [N]")
        ax.legend(fontsize=8)
    figure.suptitle(f"Cantilever fits (paper Figs. 5, 7); RMSE {result.rmse:.3g} N, noise "
                    f"{result.noise:.3g} N{' (quick mode)' if args.quick else ''}")
    save(figure, args.out)


if __name__ == "__main__":
    main()
