"""Figures of the V3 hanging test (``v3_hanging_test.py score``): the deformed kite with its
registered markers, the RMS per case beside the peers and the undeformed kite, and the
calibrated tube law."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from _v3_kite_fem import v3_tube_surfaces  # noqa: E402

import jaxtube as jt  # noqa: E402


def shape_figure(positions, score, title, path) -> None:
    """The deformed kite's tube axes (kite_fem frame, m) with the registered markers,
    coloured by their surface distance [mm]."""
    surfaces = v3_tube_surfaces(positions)
    nodes = np.asarray(surfaces.segment_nodes)
    x = np.asarray(surfaces.node_positions)
    fig = plt.figure(figsize=(8, 6))
    ax = fig.add_subplot(projection="3d")
    for a, b in nodes:
        ax.plot(*np.stack([x[a], x[b]]).T, color="0.3", lw=1.5)
    triangles = np.asarray(surfaces.canopy_triangles)
    for tri in triangles[::4]:
        loop = x[np.r_[tri, tri[0]]]
        ax.plot(*loop.T, color="0.85", lw=0.3)
    markers = np.asarray(score.registered_m)
    distance = np.asarray(score.distance_mm)
    limit = max(float(np.nanmax(np.abs(distance))), 1.0)
    points = ax.scatter(*markers.T, c=distance, cmap="coolwarm", vmin=-limit, vmax=limit, s=18,
                        depthshade=False)
    fig.colorbar(points, ax=ax, shrink=0.6, label="marker distance to tube surface [mm]")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m] (gravity)")
    ax.invert_zaxis()
    ax.set_title(title)
    span = np.ptp(x, axis=0).max() / 2
    centre = x.mean(0)
    ax.set_xlim(centre[0] - span, centre[0] + span)
    ax.set_ylim(centre[1] - span, centre[1] + span)
    ax.set_zlim(centre[2] + span, centre[2] - span)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def rms_figure(rows, peers, path, fitted_cases=(1,)) -> None:
    """Bars of RMS [mm] per case: undeformed, Billow x 0.36, kite_fem, jaxtube (its legend
    naming the cases the calibration was fitted to, ``fitted_cases``; the others are
    predicted)."""
    cases = list(rows)
    width = 0.2
    fig, ax = plt.subplots(figsize=(8, 4))
    series = [("undeformed", [rows[c]["undeformed_rms_mm"] for c in cases], "0.7"),
              ("Billow, law x 0.36 (published)", [peers[c][1] for c in cases], "tab:orange"),
              ("kite_fem (this version)", [peers[c][2] for c in cases], "tab:green"),
              (f"jaxtube (fitted to case {' and '.join(map(str, fitted_cases))}, "
               f"{', '.join(str(c) for c in cases if c not in fitted_cases)} predicted)",
               [rows[c]["rms_mm"] for c in cases],
               "tab:blue")]
    for k, (label, values, colour) in enumerate(series):
        ax.bar(np.arange(len(cases)) + (k - 1.5) * width, values, width, label=label,
               color=colour)
    ax.set_xticks(np.arange(len(cases)), [f"case {c}" for c in cases])
    ax.set_ylabel("RMS marker distance [mm] (LE + struts)")
    ax.legend(fontsize=8)
    ax.set_title("TU Delft V3 hanging test, 0.15 bar")
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def law_figure(scale, law_form, path) -> None:
    """Moment against curvature of the calibrated law (Breukels 2011 with its factor
    ``scale`` in ``law_form``: "curvature" stiffness x scale, moments kept; "moment" the whole
    curve x scale) and the unscaled law, at 0.15 and 0.25 bar, for the V3's smallest and
    largest leading-edge radius."""
    curvature = np.linspace(0.0, 1.5, 200)
    fig, ax = plt.subplots(figsize=(7, 4))
    base = jt.EmpiricalBendingLaw2011()
    law = (jt.CurvatureScaledLaw(base, scale) if law_form == "curvature"
           else jt.ScaledLaw(base, scale))
    for pressure_bar, style in ((0.15, "-"), (0.25, "--")):
        for radius, colour in ((0.0565, "tab:blue"), (0.101, "tab:red")):
            moment = np.asarray(base.moment(curvature, pressure_bar * 1e5, radius))
            calibrated = np.asarray(law.moment(curvature, pressure_bar * 1e5, radius))
            ax.plot(curvature, calibrated, style, color=colour,
                    label=f"{law_form} x {scale:.3f}: {pressure_bar} bar, "
                          f"r = {1e3 * radius:.0f} mm")
            ax.plot(curvature, moment, style, color=colour, alpha=0.3, lw=0.8)
    ax.set_xlabel("curvature [1/m]")
    ax.set_ylabel("bending moment [N m]")
    ax.set_title("Calibrated tube law (faint: Breukels 2011 unscaled)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
