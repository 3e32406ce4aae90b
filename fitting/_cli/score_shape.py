"""``jaxtube score-shape``: a solved shape against measured markers.

``jaxtube score-shape --markers MARKERS.csv --positions positions.csv --tubes TUBES.csv
[--canopy TRIANGLES.csv] [--undeformed positions0.csv] [--spanwise auto|none|G0,G1,...]
[--canopy-group CAN] --out DIR``

File formats: :mod:`fitting._shape.files` (units in the column names). The markers are
registered rigidly onto the tubes (:func:`fitting.register`) and scored
(:func:`fitting.score_shape`); with ``--undeformed`` the undeformed structure is scored the
same way, as the null model. Writes into DIR:

- ``scores.json``: RMS [mm] overall (tube markers: the peers' metric), per group, canopy;
  the registration and its search; the same for the undeformed structure (or ``null``);
- ``markers.csv``: one row per marker, ``group,idx,model_group,distance_mm,x_model_m,
  y_model_m,z_model_m,line`` (signed tube-surface distance; canopy: unsigned, empty when no
  canopy triangles are given);
- ``shape.png``: the registered markers on the model in 3-D, coloured by error.

Exit codes: 0 success; 1 written, but the registration's final Levenberg-Marquardt run did
not meet its tolerance (said in the terminal and in ``scores.json``); 2 bad input (every
problem named with file, line and column; nothing written).
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

from .._shape.figure import shape_figure
from .._shape.files import load_positions, load_triangles, load_tubes
from .._shape.markers import CANOPY_GROUP, load_markers
from .._shape.score import MARKER_CSV_COLUMNS, score_shape
from .._shape.surfaces import TubeSurfaces
from .common import write_directory

OUTPUT_FILES = ("scores.json", "markers.csv", "shape.png")


def add_score_shape(subparsers) -> None:
    """Register ``score-shape`` on an argparse subparsers object."""
    parser = subparsers.add_parser(
        "score-shape", help="score a solved shape against measured 3-D markers",
        description="Register measured markers rigidly onto a structure's tube surfaces and "
                    "write the RMS of marker-to-surface distances (overall, per group, "
                    "canopy), per-marker errors and a 3-D figure.")
    parser.add_argument("--markers", type=Path, required=True,
                        help="marker CSV: group,idx_in_group,x_m,y_m,z_m (or x_mm..., or x,y,z "
                             "in metres)")
    parser.add_argument("--positions", type=Path, required=True,
                        help="node positions CSV: node,x_m,y_m,z_m (what simulate writes)")
    parser.add_argument("--tubes", type=Path, required=True,
                        help="tube segments CSV: group,node_1,node_2,radius_m (or diameter_m, "
                             "radius_start_m,radius_end_m, _mm)")
    parser.add_argument("--canopy", type=Path, default=None,
                        help="canopy triangles CSV: node_1,node_2,node_3 (scores canopy markers)")
    parser.add_argument("--undeformed", type=Path, default=None,
                        help="undeformed node positions CSV: scored the same way (null model)")
    parser.add_argument("--spanwise", default="auto",
                        help="marker groups numbered along the span whose order may be "
                             "reversed: 'auto' (a numbered family like strut0..strut7), "
                             "'none', or a comma-separated list")
    parser.add_argument("--canopy-group", default=CANOPY_GROUP,
                        help=f"marker group on the canopy (default {CANOPY_GROUP})")
    parser.add_argument("--out", type=Path, required=True, help="output directory")
    parser.set_defaults(run=run)


def _spanwise(text: str):
    if text == "auto":
        return "auto"
    if text == "none":
        return ()
    return tuple(name.strip() for name in text.split(",") if name.strip())


def run(args) -> int:
    """Run ``score-shape``; returns the exit code."""
    try:
        markers = load_markers(args.markers)
        positions = load_positions(args.positions)
        segments = load_tubes(args.tubes, node_count=len(positions))
        triangles = None if args.canopy is None else \
            load_triangles(args.canopy, node_count=len(positions))
        surfaces = TubeSurfaces.from_segments(positions, segments, triangles)
        undeformed = None
        if args.undeformed is not None:
            undeformed = surfaces.with_positions(load_positions(args.undeformed))
        options = dict(spanwise_groups=_spanwise(args.spanwise), canopy_group=args.canopy_group)
        score = score_shape(surfaces, markers, **options)
        null = None if undeformed is None else score_shape(undeformed, markers, **options)
    except (OSError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    scores = {"markers_file": str(args.markers), "positions_file": str(args.positions),
              "tubes_file": str(args.tubes), "deformed": score.summary(),
              "undeformed": None if null is None else null.summary()}

    def write_markers(path):
        with open(path, "w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(MARKER_CSV_COLUMNS)
            for row in score.marker_rows():
                writer.writerow([("" if v != v else f"{v:.6g}") if isinstance(v, float) else v
                                 for v in row])

    write_directory(args.out, {
        "scores.json": lambda p: p.write_text(json.dumps(scores, indent=2) + "\n"),
        "markers.csv": write_markers,
        "shape.png": lambda p: shape_figure(score, surfaces, p, null=null, undeformed=undeformed),
    })
    line = f"RMS over tube markers: {score.rms_mm:.1f} mm"
    if null is not None:
        line += f" (undeformed: {null.rms_mm:.1f} mm)"
    if score.canopy_rms_mm is not None:
        line += f"; canopy markers: {score.canopy_rms_mm:.1f} mm"
    print(line)
    print("  " + ", ".join(f"{g} {v:.0f}" for g, v in score.group_rms_mm.items()) + " [mm]")
    unscored = sum(g == "canopy" for g in score.model_group) if not surfaces.has_canopy else 0
    if unscored:
        print(f"note: {unscored} canopy markers ({args.canopy_group}) not scored: no --canopy "
              f"triangles given (their distance_mm is left empty)")
    print(f"wrote {', '.join(OUTPUT_FILES)} to {args.out}")
    failed = [name for name, s in (("deformed", score), ("undeformed", null))
              if s is not None and not s.registration.converged]
    for name in failed:
        print(f"warning: the registration of the {name} shape did not converge: "
              f"{(score if name == 'deformed' else null).registration.message}", file=sys.stderr)
    return 1 if failed else 0
