"""V3 campaigns with a planted effect: does ``jaxtube shape diagnose`` name what was planted,
and nothing else, on the V3 kite?

Markers are made by a route independent of the candidates: the V3 kite with the hand-made
calibration (experiments/results/v3_model.json: bending scale 0.2696, trailing edge 0.9166)
and, per plant, one change of the generating structure, solved by each case's route
(:meth:`fitting.CaseSolver.solve`, from the model file's shape), then sampled where the real
markers of the case lie: each real tube marker registered onto the solved shape and moved to
the nearest point of its tube's surface (radius continuous), then a random rigid motion and
Gaussian noise (``--noise-mm``, default 2). Plants:

- ``none``: nothing besides the hand-made model (the verdict should add no effect);
- ``central_struts``: the two central struts' (``strut3``, ``strut4``) bending law x 2.5,
  where the candidate ``bending.struts`` scales all eight struts together;
- ``rear_bridles``: the rest lengths of one bridle group, the four rear bridle lines on each
  side (kite_fem's ``br1`` to ``br4``, from the struts' trailing ends to their knots) 3 %
  short. The planted campaign names that group as the line set ``rear_bridles``, so the
  candidates gain ``rest_length.rear_bridles`` and ``stiffness.rear_bridles``.

The diagnosis then runs on the planted campaign (the V3 campaign with the planted markers)
from the plain model with the baseline ``bending_scale`` and the trailing edge's rest
lengths, the candidates ``--candidates`` (default every other built-in effect), the
left-out cases scored by the linearised step. The plants run one after the other in one
process (one compiled program per route). Writes
``experiments/results/v3_shape_planted/<plant>/`` (``campaign/``: the campaign file and its
markers; ``diagnosis/``: the command's files) and prints each verdict.

Usage: ``python -m experiments.v3_shape_planted --plants none central_struts
[--cases P1_S ...] [--candidates bending.struts ...]``
"""

import argparse
import dataclasses
import json
import os
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from scipy.spatial.transform import Rotation

import fitting
import jaxtube as jt
from fitting._cli.shape import add_shape
from fitting._shape.surfaces import tube_surface_distance

ROOT = Path(__file__).resolve().parent
DATA = ROOT / "data" / "v3_hanging"
CASES = ["P1_S", "P1_PL1", "P1_PL2", "P1_TL1", "P1_TL2"]
# Per plant: the bending law's factor per tube class, the rest-length factor per line set.
PLANTS = {"none": ({}, {}), "central_struts": ({"central_struts": 2.5}, {}),
          "rear_bridles": ({}, {"rear_bridles": 0.97})}
# The rear bridle group of the V3 bridle (kite_fem's br1-br4 on both sides; the lines of
# kite_fem/struc_geometry_hanging_test.yaml, "bridle_connections").
REAR_BRIDLES = [[92, 85], [91, 85], [90, 84], [89, 84], [126, 119], [125, 119], [124, 118],
                [123, 118]]


def surface_markers(campaign, case, positions, rng, noise_m):
    """The case's real tube markers moved onto the tubes' surfaces at ``positions`` [N, 3],
    then a random rigid motion and noise: ``(positions [m, 3], groups, indices)``."""
    real = fitting.load_markers(case.markers)
    surfaces = fitting.continuous_radius(fitting.campaign_tube_surfaces(campaign, positions))
    registration = fitting.smooth_shape_score(
        fitting.campaign_tube_surfaces(campaign, positions), real,
        canopy_group=campaign.canopy_group).registration.registration
    groups = registration.surface_groups(real, surfaces)
    tube = np.flatnonzero(groups >= 0)
    points = jnp.asarray(registration.apply(real.position)[tube])
    point_groups = jnp.asarray(groups[tube])

    def distance(p):
        return tube_surface_distance(surfaces, p, point_groups)[0]

    for _ in range(3):  # the nearest surface point, by Newton steps along the normal
        normal = jax.grad(lambda p: jnp.sum(distance(p)))(points)
        points = points - distance(points)[:, None] * normal
    moved = Rotation.from_rotvec(rng.normal(scale=0.5, size=3)).apply(np.array(points))
    moved += rng.normal(size=3) + rng.normal(scale=noise_m, size=moved.shape)
    return moved, [real.group[k] for k in tube], [real.index[k] for k in tube]


def planted_campaign(folder: Path, plant: str, cases, candidates, noise_m: float,
                     seed: int) -> Path:
    """Write the planted campaign (markers and campaign.toml) into ``folder``."""
    campaign = fitting.read_campaign(DATA / "campaign.toml")
    bending, rest_lengths = PLANTS[plant]
    generating = dataclasses.replace(
        campaign, tube_classes={**campaign.tube_classes, "central_struts": ("strut3", "strut4")},
        line_sets={**campaign.line_sets, "rear_bridles": tuple(map(tuple, REAR_BRIDLES))})
    hand = fitting.read_model_file(ROOT / "results" / "v3_model.json", campaign)
    truth = dataclasses.replace(hand, bending_class_factors=bending, rest_length_factors={
        **hand.rest_length_factors, **rest_lengths})
    solver = fitting.CaseSolver(generating)
    rng = np.random.default_rng(seed)
    text = (DATA / "campaign.toml").read_text()
    if rest_lengths:  # the planted group is a line set of the planted campaign
        text = text.replace("[line_sets]\n", f"[line_sets]\nrear_bridles = {REAR_BRIDLES}\n")
    for relative in ("kite_fem/initial.npz", "kite_fem/validation_data.csv"):
        text = text.replace(f'"{relative}"', json.dumps(os.path.relpath(DATA / relative,
                                                                        folder)))
    text = text.replace('baseline = ["bending_scale"]',
                        'baseline = ["bending_scale", "rest_length_factors.trailing_edge"]'
                        + ("" if candidates is None else
                           f"\ncandidates = {json.dumps(list(candidates))}"))
    folder.mkdir(parents=True, exist_ok=True)
    for name in cases:
        case = campaign.case(name)
        solved = solver.solve(case, truth)
        if not solved.converged:
            raise RuntimeError(f"{name}: the planted kite does not converge")
        points, groups, indices = surface_markers(campaign, case, solved.positions, rng,
                                                  noise_m)
        (folder / f"{name}.csv").write_text("group,idx_in_group,x_m,y_m,z_m\n" + "".join(
            f"{g},{k},{x:.17g},{y:.17g},{z:.17g}\n"
            for g, k, (x, y, z) in zip(groups, indices, points)))
        text = text.replace(f'"markers/{name}.csv"', f'"{name}.csv"')
        print(f"{name}: {len(points)} tube markers, planted {plant}", flush=True)
    for name in CASES:
        if name not in cases:  # a case left out of this run is predicted only
            text = text.replace(f'markers = "markers/{name}.csv"', 'role = "predict"')
    (folder / "campaign.toml").write_text(text)
    return folder / "campaign.toml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plants", nargs="+", choices=PLANTS, required=True)
    parser.add_argument("--cases", nargs="+", default=CASES, choices=CASES)
    parser.add_argument("--candidates", nargs="+", default=None,
                        help="candidate effects (default: every built-in effect)")
    parser.add_argument("--noise-mm", type=float, default=2.0)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    jt.enable_compilation_cache()
    for plant in args.plants:
        out = ROOT / "results" / "v3_shape_planted" / plant
        path = planted_campaign(out / "campaign", plant, args.cases, args.candidates,
                                args.noise_mm / 1e3, args.seed)
        command = argparse.ArgumentParser()
        add_shape(command.add_subparsers())
        diagnose = command.parse_args(["shape", "diagnose", str(path), "--out",
                                       str(out / "diagnosis")])
        code = diagnose.run(diagnose)
        verdict = json.loads((out / "diagnosis" / "diagnosis.json").read_text())
        print(f"planted {plant}: added {verdict['added']} (exit {code})", flush=True)


if __name__ == "__main__":
    main()
