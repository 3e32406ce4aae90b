"""Paper Fig. 9: the tube kite's force against crown deflection (the static kite test).

The paper's test: a surf kite's leading-edge tube (one envelope, double tapered, 0.25 bar)
fixed at both wing tips with the arc upright, its crown pushed down in displacement control
through wrinkling; it measured about 0-70 N over 0-140 mm. The measurements and the kite's
geometry are not public, so this is a stand-in of the same kind, computed by jaxtube itself
(no measured-style data here): the kite of ``experiments/tube_kite.py`` (span 2.6 m, arc
height 1.0 m, radius 85 mm at the centre to 45 mm at the tips, tension-field law
E t = 150 kN/m, 0.25 kg/m self-weight), the leading edge alone at two segment counts (the
finer one shows the discretisation error) and, in full mode, with four chordwise struts.
Points are coloured by the worst joint regime along the kite; the printed summary gives
the crown deflections where wrinkling and collapse first appear. The struts carry only
their own weight in this test, so they ride along almost rigidly and change the curve
little (full mode: peak 161 N with and without them, wrinkling from 7 mm, collapse from
119 mm).

    python -m experiments.fig9_kite_force_deflection [--quick] [--out FILE.png]

Quick mode (CI): the leading edge alone, 12 segments, 12 steps.
"""


import matplotlib

matplotlib.use("Agg")
import jax
import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np

import jaxtube as jt
from experiments._synthetic import parser, save
from experiments.tube_kite import build_kite

MAX_DEFLECTION = 0.14  # m, the paper's range
REGIME_COLOURS = ("C0", "C1", "C3")


def crown_curve(segments: int, struts: int, steps: int):
    """Crown displacements [m] ``[K]``, actuator force [N], worst regime, converged."""
    kite = build_kite(segments, struts)
    structure, params = kite.build()
    crown = structure.node_id(kite.node("le:centre"))
    displacement = np.linspace(0.0, MAX_DEFLECTION, steps + 1)[1:]
    path = jt.DisplacementControl(crown, [0.0, 0.0, -1.0], jnp.asarray(displacement))
    solution = jax.jit(lambda p: jt.solve_path(structure, p, path))(params)
    return (displacement, np.asarray(solution.control_force),
            np.asarray(solution.joint_regime).max(axis=1), np.asarray(solution.converged))


def main() -> None:
    args = parser("fig9_kite_force_deflection", __doc__.splitlines()[0]).parse_args()
    if args.quick:
        cases = [("leading edge, 12 segments", 12, 0, 12, "-")]
    else:
        cases = [("leading edge, 12 segments", 12, 0, 40, ":"),
                 ("leading edge, 24 segments", 24, 0, 40, "-"),
                 ("leading edge + 4 struts, 24 segments", 24, 4, 40, "--")]
    figure, ax = plt.subplots(figsize=(7.5, 4.8), constrained_layout=True)
    lines = []
    for label, segments, struts, steps, style in cases:
        u, force, regime, converged = crown_curve(segments, struts, steps)
        good = converged & np.isfinite(force)
        ax.plot(np.r_[0.0, u[good]] * 1e3, np.r_[0.0, force[good]], style, color="0.4",
                lw=1.2, label=label)
        for level, colour in enumerate(REGIME_COLOURS):
            chosen = good & (regime == level)
            ax.scatter(u[chosen] * 1e3, force[chosen], s=14, color=colour, zorder=3)
        if (~converged).any():
            ax.scatter(u[~converged] * 1e3, np.nan_to_num(force[~converged]), marker="x",
                       color="k", zorder=4, label=f"{label}: not converged")
        text = f"{label}: peak {force[good].max():.0f} N"
        for level, name in ((1, "wrinkling"), (2, "collapse")):
            if (regime[good] >= level).any():
                at = u[good][np.argmax(regime[good] >= level)]
                text += f", {name} from {at * 1e3:.0f} mm"
        lines.append(text)
        print(text + f" ({int(converged.sum())}/{converged.size} steps converged)")
    for level, name in enumerate(("unwrinkled", "wrinkled", "collapsed")):
        ax.scatter([], [], s=14, color=REGIME_COLOURS[level], label=f"worst joint {name}")
    ax.set_xlabel("crown deflection [mm]")
    ax.set_ylabel("actuator force [N]")
    ax.set_title("tube kite, tips clamped, crown pushed down (paper Fig. 9, stand-in kite)"
                 + (" - quick mode" if args.quick else ""), fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    save(figure, args.out)


if __name__ == "__main__":
    main()
