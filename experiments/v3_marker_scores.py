"""V3 hanging test: the peers' shape metric on the undeformed kite and kite_fem's own states.

Scores, by :func:`fitting.score_shape` (rigid registration of the markers onto the tube
surfaces, RMS over leading-edge and strut markers of axis distance minus radius; canopy
markers against the canopy triangles, separately), the undeformed V3 model of kite_fem
(``initial.npz``, the null model) and kite_fem's solved states of cases 1-5 against the five
0.15 bar marker files, beside the published numbers (data README: undeformed 695, 654, 639,
139, 99 mm; kite_fem states by an independent implementation 169, 369, 389, 112, 79 mm).

Data: "Structural model data from awegroup/kite_fem (MIT, (c) 2025 Patrick Roeleveld);
marker data from pimjhaanen/photogrammetry_thesis (MIT, (c) 2026 PJ Haanen)".

Run from the repository root: ``python -m experiments.v3_marker_scores`` (writes
``experiments/results/v3_marker_scores.json`` and ``.txt``; ``--out DIR`` elsewhere).
"""

import argparse
import json
import time
from pathlib import Path

import numpy as np

import fitting

DATA = Path(__file__).resolve().parent / "data" / "v3_hanging"
CASES = ("P1_S", "P1_PL1", "P1_PL2", "P1_TL1", "P1_TL2")

PUBLISHED_UNDEFORMED_MM = (695, 654, 639, 139, 99)
PUBLISHED_KITE_FEM_STATES_MM = (169, 369, 389, 112, 79)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "results")
    args = parser.parse_args(argv)
    campaign = fitting.read_campaign(DATA / "campaign.toml")
    undeformed = fitting.campaign_tube_surfaces(campaign)
    rows, lines = [], []
    header = (f"{'case':>7} {'undeformed':>10} {'published':>9} {'kite_fem':>9} "
              f"{'published':>9} {'canopy undef.':>13} {'canopy kite_fem':>15} {'order':>9}")
    lines.append(header)
    for k, case in enumerate(CASES):
        markers = fitting.load_markers(campaign.case(case).markers)
        started = time.perf_counter()
        null = fitting.score_shape(undeformed, markers)
        solved = np.load(DATA / "kite_fem" / "states" / f"load_case_{k + 1}.npz")
        state = fitting.score_shape(
            undeformed.with_positions(solved["coords_current"].reshape(-1, 3)), markers)
        seconds = time.perf_counter() - started
        rows.append({"case": case, "load_case": k + 1,
                     "undeformed": null.summary(), "kite_fem_state": state.summary(),
                     "published_undeformed_mm": PUBLISHED_UNDEFORMED_MM[k],
                     "published_kite_fem_state_mm": PUBLISHED_KITE_FEM_STATES_MM[k],
                     "seconds_both": seconds})
        order = "reversed" if null.registration.registration.reversed_order else "as named"
        lines.append(f"{case:>7} {null.rms_mm:>10.1f} {PUBLISHED_UNDEFORMED_MM[k]:>9d} "
                     f"{state.rms_mm:>9.1f} {PUBLISHED_KITE_FEM_STATES_MM[k]:>9d} "
                     f"{null.canopy_rms_mm:>13.1f} {state.canopy_rms_mm:>15.1f} {order:>9}")
        print(lines[-1], f"({seconds:.1f} s)", flush=True)
    lines.append("RMS in mm over LE + strut markers (the peers' metric); canopy markers: distance "
                 "to the nearest canopy triangle, same registration.")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "v3_marker_scores.json").write_text(json.dumps(rows, indent=2) + "\n")
    (args.out / "v3_marker_scores.txt").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
