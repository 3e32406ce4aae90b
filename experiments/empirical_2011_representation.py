"""How well the spline family represents Breukels' 2011 empirical law.

Measured-style data: curves of :class:`jaxtube.EmpiricalBendingLaw2011` across its reported
validity range (r = 0.05-0.15 m, 0.1-1 bar; 1 m cantilever) from the independent continuum
solver, up to 85 % of the law's collapsed-regime moment, with 0.5 % force noise. The spline
law with the paper's scaling ``A (p r^3)^B`` (pivots 1,1,1) is fitted to all curves at once;
the figure shows the curves, the fit, and per curve the RMSE of the fitted model against
the noise-free 2011-law curve, relative to that curve's largest force (the representation
error; the noise, 0.5 % of the largest force of all curves, is left out of it).
In full mode the spline with the separate scaling ``A p^B r^C`` is fitted too: the 2011
law's parameters depend on pressure and radius separately, not only through ``p r^3``, so
the comparison shows how much of the error is the scaling form and how much the spline.

    python -m experiments.empirical_2011_representation [--quick] [--out FILE.png]
"""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from experiments._synthetic import QUICK_POINTS, continuum_curve, fit, jt, measured, parser, save


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
    separate = None if args.quick else fit(data, False, form="separate")
    figure, (left, right) = plt.subplots(1, 2, figsize=(12, 5), constrained_layout=True)
    def representation_errors(fitted):
        """Per curve: RMSE of the fitted model against the noise-free 2011-law curve (the
        continuum solution interpolated at the measured deflections), in % of its largest
        force. The noise (one level for all curves) is left out, so small curves are not
        judged by it."""
        out = []
        for curve, model, (_, _, _, _, true_u, true_f) in zip(data, fitted.force, curves):
            truth = np.interp(curve.deflection, true_u, true_f)
            out.append(100 * np.sqrt(np.mean((model - truth) ** 2)) / true_f.max())
        return out

    errors = representation_errors(result)
    for k, (curve, model) in enumerate(zip(data, result.force)):
        order = np.argsort(curve.deflection)
        left.plot(curve.deflection * 1e3, curve.force, "o", ms=3, color=f"C{k % 10}")
        left.plot(curve.deflection[order] * 1e3, model[order], "-", color=f"C{k % 10}",
                  label=curve.name)
    left.set_xlabel("tip deflection [mm]")
    left.set_ylabel("tip load [N]")
    left.set_title("2011 law (points) and fitted spline (lines)")
    left.legend(fontsize=7)
    x = np.arange(len(errors))
    width = 0.4 if separate is not None else 0.8
    right.bar(x - (width / 2 if separate is not None else 0), errors, width,
              label=f"paper form A (p r^3)^B: RMSE {result.rmse:.3g} N")
    title = (f"error against the noise-free law, per curve (noise {result.noise:.2g} N); "
             f"fit RMSE paper {result.rmse:.3g} N")
    if separate is not None:
        errors_separate = representation_errors(separate)
        right.bar(x + width / 2, errors_separate, width,
                  label=f"separate form A p^B r^C: RMSE {separate.rmse:.3g} N")
        title += f", separate {separate.rmse:.3g} N"
        for name, value in zip((c.name for c in data), errors_separate):
            print(f"  {name:<22} separate form: RMSE {value:5.2f} % of the largest force")
    for name, value in zip((c.name for c in data), errors):
        print(f"  {name:<22} paper form:    RMSE {value:5.2f} % of the largest force")
    right.set_xticks(x, [c.name for c in data], rotation=60, ha="right", fontsize=7)
    right.set_ylabel("RMSE vs noise-free curve / its max force [%]")
    right.legend(fontsize=8)
    right.set_title(title, fontsize=10)
    figure.suptitle("Spline + p r^3 scaling against Breukels' 2011 empirical law"
                    f"{' (quick mode)' if args.quick else ''}")
    save(figure, args.out)


if __name__ == "__main__":
    main()
