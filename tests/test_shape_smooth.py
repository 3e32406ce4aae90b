"""The smooth marker metric (radius continuous along each tube) on a small kite hung
through a campaign: its gradient through the equilibrium (implicit function theorem, forward
mode) against central differences of the re-registered metric, and its optimum against the
peers' score. Markers are drawn on the kite solved at a planted bending scale and rest
length of the bridle, moved by a rigid motion, with 1 mm noise.

One compiled program serves every test here: the staged hang of the small kite under
``jax.jacfwd`` (:meth:`fitting.CaseSolver.tangents`), which returns the equilibrium and its
tangents; finite differences and the searches reuse it at other values.
"""

import argparse
import json

import numpy as np
import pytest
from scipy.optimize import minimize_scalar
from scipy.spatial.transform import Rotation

import fitting
from fitting import continuous_radius, smooth_shape_score
from fitting._campaign.solve import _PROGRAMS
from fitting._cli.shape import add_shape

from .kite_fem_mini import write_mini_kite

NAMES = ("bending_scale", "rest_length_factors.bridle")
PLANTED = (0.4, 0.97)
#: Values searched as they are (a mass [kg], offsets [bar], [mm]); the solver differentiates
#: with respect to these too, so that one compiled program serves every test here.
OFFSETS = ("point_masses_kg.knot", "pressure_offset_bar", "suspension_offsets_mm.11.y",
           "suspension_offsets_mm.12.y")
NOISE_M = 0.001

CAMPAIGN = """
[structure]
kite_fem = "mini.npz"
suspension = [11, 12]

[tubes]
LE = [1, 5]
strut0 = [2, 7]
strut1 = [4, 9]

[line_sets]
bridle = [[11, 1], [11, 2], [12, 4], [12, 5]]

[points]
centre = 3
knot = 10

[hang]
load_stages = [0.5, 1.0]
max_newton_steps = 100

[[cases]]
name = "hung"
pressure_bar = 0.05
loads = [{node = 3, mass_kg = 1.0}]
route = "stages"
markers = "markers.csv"
"""


def surface_points(surfaces, rng, per_segment=3):
    """Points on the tube surfaces (continuous radius), with their groups."""
    smooth = continuous_radius(surfaces)
    x = np.asarray(smooth.node_positions)
    points, groups = [], []
    for s, (a, b) in enumerate(np.asarray(smooth.segment_nodes)):
        axis = x[b] - x[a]
        for _ in range(per_segment):
            t = rng.uniform(0.15, 0.85)
            normal = np.cross(axis, rng.normal(size=3))
            normal /= np.linalg.norm(normal)
            radius = float(smooth.radius_start[s] + t * (smooth.radius_end[s]
                                                         - smooth.radius_start[s]))
            points.append(x[a] + t * axis + radius * normal)
            groups.append(smooth.group_names[int(smooth.segment_group[s])])
    return np.asarray(points), groups


@pytest.fixture(scope="module")
def kite(tmp_path_factory):
    folder = tmp_path_factory.mktemp("campaign")
    write_mini_kite(folder / "mini.npz")
    (folder / "markers.csv").write_text("group,idx_in_group,x_m,y_m,z_m\n")
    (folder / "campaign.toml").write_text(CAMPAIGN)
    campaign = fitting.read_campaign(folder / "campaign.toml")
    case = campaign.case("hung")
    solver = fitting.CaseSolver(campaign, tangent_values=NAMES + OFFSETS)

    def solve(values, names=NAMES):
        model = fitting.with_values(fitting.KiteModel(), names, values)
        positions, tangents, converged = solver.tangents(case, model, names)
        assert converged
        return positions, tangents

    planted, _ = solve(PLANTED)
    rng = np.random.default_rng(3)
    points, groups = surface_points(fitting.campaign_tube_surfaces(campaign, planted), rng)
    moved = Rotation.from_rotvec([0.3, -1.2, 0.8]).apply(points) + [1.0, 2.0, -0.5]
    moved += rng.normal(scale=NOISE_M, size=moved.shape)
    (folder / "markers.csv").write_text("group,idx_in_group,x_m,y_m,z_m\n" + "".join(
        f"{g},{k},{x:.17g},{y:.17g},{z:.17g}\n"
        for k, (g, (x, y, z)) in enumerate(zip(groups, moved))))
    markers = fitting.load_markers(case.markers)
    return campaign, solve, markers


def smooth_metric(kite, values):
    campaign, solve, markers = kite
    positions, tangents = solve(values)
    score = smooth_shape_score(fitting.campaign_tube_surfaces(campaign, positions), markers)
    return score.rms_mm, 1e3 * np.einsum("nd,ndk->k", score.position_gradient, tangents)


def peers_metric(kite, values):
    campaign, solve, markers = kite
    positions, _ = solve(values)
    return fitting.score_shape(fitting.campaign_tube_surfaces(campaign, positions),
                               markers).rms_mm


def test_smooth_metric_gradient_through_the_equilibrium_matches_central_differences(kite):
    """d RMS / d log(value) [mm]: the position gradient at the optimal registration times
    the equilibrium's tangents, against central differences of the re-registered metric
    (step h and h/2 agree, so their truncation error is below the tolerance)."""
    theta = np.log([0.8, 1.0])
    _, gradient = smooth_metric(kite, np.exp(theta))
    assert np.all(np.abs(gradient) > 0.1)  # both values move the markers' fit
    for k in range(2):
        estimates = []
        for h in (2e-3, 1e-3):
            step = np.eye(2)[k] * h
            plus, _ = smooth_metric(kite, np.exp(theta + step))
            minus, _ = smooth_metric(kite, np.exp(theta - step))
            estimates.append((plus - minus) / (2 * h))
        assert estimates[1] == pytest.approx(estimates[0], rel=1e-3)
        assert gradient[k] == pytest.approx(estimates[1], rel=2e-3)


def test_tangents_in_a_point_mass_and_offsets(kite):
    """The equilibrium's tangents in a point mass [kg], the pressure offset [bar] and the
    suspension points' offsets [mm] (searched as they are) against central differences of
    the positions; moving both suspension points by 1 mm along y translates every node by
    1 mm along y (gravity is the same everywhere: a rigid motion is an equilibrium)."""
    _, solve, _ = kite
    names = NAMES + OFFSETS
    values = np.array(PLANTED + (0.3, 0.0, 0.0, 0.0))
    positions, tangents = solve(values, names)
    free = np.abs(tangents[..., 2]).max(axis=1) > 0  # nodes a dead load moves
    assert free.sum() >= 10
    np.testing.assert_allclose(tangents[free][..., 4:].sum(axis=-1), np.tile(
        [0.0, 1e-3, 0.0], (free.sum(), 1)), atol=1e-9)
    for k, h in ((2, 5e-3), (3, 5e-4), (4, 1.0)):
        step = np.eye(len(names))[k] * h
        central = (solve(values + step, names)[0] - solve(values - step, names)[0]) / (2 * h)
        scale = np.abs(tangents[..., k]).max()
        assert scale > 0
        np.testing.assert_allclose(tangents[..., k], central, atol=2e-4 * scale)


def test_a_model_set_in_another_order_shares_the_compiled_program(kite):
    """The same values set in the reverse order (dictionaries in another order) solve with
    the program already compiled, to the same positions."""
    _, solve, _ = kite
    names = NAMES + OFFSETS
    values = np.array(PLANTED + (0.3, 0.01, 2.0, -1.0))
    positions, _ = solve(values, names)
    programs = len(_PROGRAMS)
    again, _ = solve(values[::-1], names[::-1])
    assert len(_PROGRAMS) == programs
    np.testing.assert_allclose(again, positions, atol=1e-9)


def test_smooth_optimum_is_the_peers_score_within_a_millimetre(kite):
    """Over the bending scale (the bridle at its planted length): the smooth metric's least
    RMS and the peers' least RMS differ by less than 1 mm, and the peers' score at the
    smooth optimum is within 1 mm of its own least."""
    bridle = PLANTED[1]
    bounds = (np.log(0.1), np.log(2.0))
    smooth = minimize_scalar(lambda t: smooth_metric(kite, (np.exp(t), bridle))[0],
                             bounds=bounds, method="bounded", options={"xatol": 1e-2})
    peers = minimize_scalar(lambda t: peers_metric(kite, (np.exp(t), bridle)),
                            bounds=bounds, method="bounded", options={"xatol": 1e-2})
    assert abs(smooth.fun - peers.fun) < 1.0
    assert peers_metric(kite, (np.exp(smooth.x), bridle)) < peers.fun + 1.0
    # The planted scale is found (the markers carry 1 mm noise).
    assert np.exp(smooth.x) == pytest.approx(PLANTED[0], rel=0.15)


def test_calibration_recovers_the_planted_values_with_standard_errors(kite):
    """``fitting.calibrate_campaign`` from the plain model (both values 1) finds the planted
    values within three standard errors, says every value is determined, and lowers the
    RMS."""
    campaign, _, _ = kite
    found = fitting.calibrate_campaign(campaign, fitting.KiteModel(), NAMES, ["hung"],
                                       fitting.CaseSolver(campaign), log=lambda text: None)
    assert found.converged, found.message
    assert found.statements == ()
    assert np.all(np.isfinite(found.standard_errors)) and np.all(found.standard_errors > 0)
    assert np.all(np.abs(found.values - PLANTED) < 3 * found.standard_errors)
    assert found.values == pytest.approx(PLANTED, rel=0.1)
    assert found.rms_mm_after["hung"] < 0.5 * found.rms_mm_before["hung"]
    assert found.model.rest_length_factors["bridle"] == pytest.approx(found.values[1])


def test_calibrate_command_writes_the_model_and_refuses_unknown_values(kite, tmp_path):
    """``jaxtube shape calibrate`` writes model.json (values, standard errors), the cases
    before and after and the figure; an unknown value is refused and nothing is written."""
    campaign, _, _ = kite
    parser = argparse.ArgumentParser()
    add_shape(parser.add_subparsers())
    arguments = ["shape", "calibrate", str(campaign.path), "--values"]
    args = parser.parse_args(arguments + ["bending_scale", "--out", str(tmp_path / "bad")])
    args.values = ["rest_length_factors.canopy"]
    assert args.run(args) == 2 and not (tmp_path / "bad").exists()
    args = parser.parse_args(arguments + list(NAMES) + ["--out", str(tmp_path / "out")])
    assert args.run(args) == 0
    written = json.loads((tmp_path / "out" / "model.json").read_text())
    fitted = written["fitted"]
    assert fitted["bending_scale"]["value"] == pytest.approx(PLANTED[0], rel=0.1)
    assert fitted["rest_length_factors.bridle"]["standard_error"] > 0
    assert written["model"]["rest_length_factors"]["bridle"] == pytest.approx(
        fitted["rest_length_factors.bridle"]["value"])
    assert fitting.read_model_file(tmp_path / "out" / "model.json", campaign).bending_scale \
        == pytest.approx(fitted["bending_scale"]["value"])
    assert (tmp_path / "out" / "rms_before_after.png").read_bytes()[:4] == b"\x89PNG"
