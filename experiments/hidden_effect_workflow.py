"""The hidden-effect workflow, before and after: the diagnosis of the bundled demo data.

``jaxtube/data/demo_hidden_effect.csv`` holds six bench cantilever curves (0.15-0.3 bar,
r = 60-90 mm, L = 0.6-1.2 m) made by an independent route, the continuum shooting solver
``fitting.continuum`` (scipy; it does not use jaxtube's solver), with a physical effect the
plain bending model lacks: the rig's clamp is a rotational spring of 1500 N m/rad
(``jaxtube/data/README.md``). ``fitting.diagnose`` starts from the plain three-regime spline
with the paper scaling, ranks the candidate effects, adds the significant one and refits.

The figure: residuals along every curve before (top left) and after (top right), with the
+-2 sigma noise band; the candidates' BIC drops at the first step (bottom left; green:
significant); the RMSE of every curve before and after, against the noise (bottom right).
This is what ``jaxtube demo`` computes; the figure puts the story on one page.

    python -m experiments.hidden_effect_workflow [--quick] [--out FILE.png]

Quick mode (CI): short fits (iteration caps), one addition at most; it checks that the
script runs, not the quality of the diagnosis.
"""

from importlib import resources

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import fitting
from experiments._synthetic import parser, save

HIDDEN = ("clamp_compliance", 1.0 / 1500.0)  # effect and its value [rad/(N m)]


def residual_panel(ax, result, title):
    for curve, model in zip(result.problem.data, result.force):
        order = np.argsort(curve.deflection)
        ax.plot(curve.deflection[order] * 1e3, (model - curve.force)[order], "o-", ms=3,
                lw=0.8, label=curve.name)
    ax.axhspan(-2 * result.noise, 2 * result.noise, color="0.85", zorder=0,
               label="+-2 sigma noise")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("tip deflection [mm]")
    ax.set_ylabel("model - measured [N]")
    ax.set_title(f"{title}: RMSE {result.rmse:.3g} N (noise {result.noise:.3g} N)",
                 fontsize=10)


def main() -> None:
    args = parser("hidden_effect_workflow", __doc__.splitlines()[0]).parse_args()
    data = fitting.load_measurements(
        str(resources.files("jaxtube") / "data" / "demo_hidden_effect.csv"))
    # Quick mode changes only the iteration caps: the compiled model is the one of
    # `jaxtube demo` (and of the tests that diagnose 6 x 14-point data), so a persistent
    # compilation cache serves it.
    options = (fitting.DiagnoseOptions(max_additions=1, baseline_iterations=8,
                                       refit_iterations=3, progress=False)
               if args.quick else fitting.DiagnoseOptions())
    diagnosis = fitting.diagnose(data, options=options)
    print(diagnosis.report())
    final = diagnosis.final

    figure, axes = plt.subplots(2, 2, figsize=(12, 8.5), constrained_layout=True)
    residual_panel(axes[0, 0], diagnosis.baseline, "before: plain bending model")
    added = " + ".join(diagnosis.verdict) or "nothing added"
    residual_panel(axes[0, 1], final, f"after: + {added}")
    limit = max(abs(np.array(axes[0, 0].get_ylim())).max(),
                abs(np.array(axes[0, 1].get_ylim())).max())
    for ax in axes[0]:
        ax.set_ylim(-limit, limit)
    axes[0, 0].legend(fontsize=7, ncol=2)

    rows = diagnosis.steps[0].candidates if diagnosis.steps else diagnosis.final_candidates
    fitting.draw_ranking(axes[1, 0], rows, diagnosis.options.bic_threshold,
                         "step 1: which effect is missing?")
    models = [("before", diagnosis.baseline), ("after", final)]
    found = ""
    if HIDDEN[0] in diagnosis.verdict:
        value = diagnosis.to_json()["final"]["effects"].get(
            f"{HIDDEN[0]}.compliance")
        if value is not None:
            found = f"; compliance found {value:.3g}, hidden {HIDDEN[1]:.3g} rad/(N m)"
    fitting.draw_rmse_per_curve(axes[1, 1], models, diagnosis.noise,
                                "error per curve" + found)
    figure.suptitle("hidden-effect workflow on jaxtube/data/demo_hidden_effect.csv (hidden: "
                    f"clamp compliance); verdict: {added}"
                    + (" - quick mode" if args.quick else ""), fontsize=11)
    save(figure, args.out)


if __name__ == "__main__":
    main()
