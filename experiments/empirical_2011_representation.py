"""How well the spline family represents Breukels' 2011 empirical law.

Measured-style data: curves of :class:`jaxtube.EmpiricalBendingLaw2011` across its reported
validity range (r = 0.05-0.15 m, 0.1-1 bar; 1 m cantilever) from the independent continuum
solver, up to 85 % of the law's collapsed-regime moment, with 0.5 % force noise. The spline
law with the paper's scaling ``A (p r^3)^B`` (pivots 1,1,1) is fitted to all curves at once;
the figure shows the curves, the fit, and each curve's RMSE relative to its largest force.

    python experiments/empirical_2011_representation.py [--quick] [--out FILE.png]
"""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from _synthetic import QUICK_POINTS, continuum_curve, fit, jt, measured, parser, save


def main() -> None:
    args = parser("empirical_2011_representation", __doc__.splitlines()[0]).parse_args()
    law = jt.EmpiricalBendingLaw2011()
    specimens = ([(0.2, 0.075), (0.6, 0.1)] if args.quick else
                 [(p, r) for p in (0.1, 0.4, 1.0) for r in (0.05, 0.1, 0.15)])
    points = QUICK_POINTS if args.quick else 12
    curves = [(f"{p:g} bar, r {r * 1e3:g} mm", p, r, 1.0,
               *continuum_curve(law, p * 1e5, r, 1.0, points)) for p, r in specimens]
    data = measured(curves, noise_fraction=0.005)
    result = fit(data, args.quick)
    figure, (left, right) = plt.subplots(1, 2, figsize=(12, 5), constrained_layout=True)
    errors = []
    for k, (curve, model) in enumerate(zip(data, result.force)):
        order = np.argsort(curve.deflection)
        left.plot(curve.deflection * 1e3, curve.force, "o", ms=3, color=f"C{k % 10}")
        left.plot(curve.deflection[order] * 1e3, model[order], "-", color=f"C{k % 10}",
                  label=curve.name)
        errors.append(100 * np.sqrt(np.mean((model - curve.force) ** 2)) / curve.force.max())
    left.set_xlabel("tip deflection [mm]")
    left.set_ylabel("tip load [N]")
    left.set_title("2011 law (points) and fitted spline (lines)")
    left.legend(fontsize=7)
    right.bar(range(len(errors)), errors)
    right.set_xticks(range(len(errors)), [c.name for c in data], rotation=60, ha="right",
                     fontsize=7)
    right.set_ylabel("RMSE / max force [%]")
    right.set_title(f"fit error per curve (noise 0.5 %); overall RMSE {result.rmse:.3g} N")
    figure.suptitle("Spline + p r^3 scaling against Breukels' 2011 empirical law"
                    f"{' (quick mode)' if args.quick else ''}")
    save(figure, args.out)


if __name__ == "__main__":
    main()
