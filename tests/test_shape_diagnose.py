"""``jaxtube shape diagnose`` on the small test kite: three hung cases whose markers are drawn
on the kite solved with a planted bending scale and, in one campaign, the bridle's rest
lengths shortened by 3 % (an independent change of the generating structure), moved by a
rigid motion, with 1 mm noise. The verdict names the planted effect and no other; with
nothing planted it names none. Candidate effects are checked (built-ins, a user's file,
unknown names refused with the key, nothing written).

All fits share one compiled program (the staged hang differentiated with respect to every
value of the candidates, :class:`fitting.CaseSolver` ``tangent_values``).
"""

import argparse
import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import fitting
import jaxtube as jt
from fitting._cli.shape import add_shape

from .kite_fem_mini import mini_kite_arrays, write_mini_kite
from .test_shape_smooth import CAMPAIGN as SMOOTH_CAMPAIGN
from .test_shape_smooth import surface_points

BENDING = 0.4
#: The planted effect and a physical decoy close to the baseline's bending scale (the
#: bending law depends on the pressure); two keep each diagnosis near a CPU-minute.
CANDIDATES = ["rest_length.bridle", "pressure"]

CAMPAIGN = SMOOTH_CAMPAIGN.split("[[cases]]")[0] + """
[tube_classes]
leading_edge = ["LE"]
struts = ["strut0", "strut1"]

[diagnose]
baseline = ["bending_scale"]
candidates = {candidates}
""" + "".join(f"""
[[cases]]
name = "{name}"
pressure_bar = 0.05
loads = [{{node = {node}, mass_kg = {mass}}}]
route = "stages"
markers = "{name}.csv"
""" for name, node, mass in (("centre", 3, 1.0), ("strut0", 7, 0.6), ("strut1", 9, 0.6)))


def write_campaign(folder, bridle: float):
    """The campaign in ``folder`` with markers of the kite at bending scale ``BENDING`` and
    the bridle's rest lengths times ``bridle``."""
    write_mini_kite(folder / "mini.npz")
    text = CAMPAIGN.replace("{candidates}", json.dumps(CANDIDATES))
    for name in ("centre", "strut0", "strut1"):
        (folder / f"{name}.csv").write_text("group,idx_in_group,x_m,y_m,z_m\n")
    (folder / "campaign.toml").write_text(text)
    campaign = fitting.read_campaign(folder / "campaign.toml")
    planted = fitting.KiteModel(bending_scale=BENDING,
                                rest_length_factors={"bridle": bridle})
    solver = fitting.CaseSolver(campaign)
    rng = np.random.default_rng(5)
    for case in campaign.cases:
        solved = solver.solve(case, planted)
        assert solved.converged
        points, groups = surface_points(
            fitting.campaign_tube_surfaces(campaign, solved.positions), rng)
        moved = Rotation.from_rotvec(rng.normal(size=3)).apply(points) + rng.normal(size=3)
        moved += rng.normal(scale=0.001, size=moved.shape)
        case.markers.write_text("group,idx_in_group,x_m,y_m,z_m\n" + "".join(
            f"{g},{k},{x:.17g},{y:.17g},{z:.17g}\n"
            for k, (g, (x, y, z)) in enumerate(zip(groups, moved))))
    return folder / "campaign.toml"


def run_diagnose(campaign_path, out, *extra):
    parser = argparse.ArgumentParser()
    add_shape(parser.add_subparsers())
    args = parser.parse_args(["shape", "diagnose", str(campaign_path), "--out", str(out),
                              *extra])
    return args.run(args)


def test_diagnosis_names_the_planted_bridle_and_nothing_else(tmp_path):
    """Bridle 3 % short: the verdict adds rest_length.bridle alone, recovers it within three
    standard errors, lowers the cases' mean square error, and writes a model that
    ``predict`` reads."""
    campaign_path = write_campaign(tmp_path, bridle=0.97)
    assert run_diagnose(campaign_path, tmp_path / "out") == 0
    diagnosis = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert diagnosis["added"] == ["rest_length.bridle"]
    fitted = diagnosis["final"]["fitted"]["rest_length_factors.bridle"]
    assert abs(fitted["value"] - 0.97) < 3 * fitted["standard_error"]
    assert diagnosis["final"]["fitted"]["bending_scale"]["value"] == pytest.approx(
        BENDING, rel=0.1)
    first = {c["effect"]: c for c in diagnosis["steps"][0]["candidates"]}
    assert first["rest_length.bridle"]["passes"]
    assert first["rest_length.bridle"]["held_out_gain_mm2"] > 0
    assert not any(c["passes"] for c in diagnosis["steps"][-1]["candidates"])
    final = diagnosis["final"]["rms_mm_after"]
    baseline = diagnosis["baseline"]["rms_mm_after"]
    assert np.mean(np.square(list(final.values()))) < \
        0.8 * np.mean(np.square(list(baseline.values())))
    campaign = fitting.read_campaign(campaign_path)
    model = fitting.read_model_file(tmp_path / "out" / "model.json", campaign)
    assert model.rest_length_factors["bridle"] == pytest.approx(fitted["value"])
    assert "missing: rest_length.bridle" in (tmp_path / "out" / "report.txt").read_text()
    assert (tmp_path / "out" / "ranking.png").read_bytes()[:4] == b"\x89PNG"


def test_nothing_planted_gets_no_effect(tmp_path):
    """Scoring the left-out cases by refitting (the planted test above scores them by the
    linearised step): no candidate is added either way. The collapse factor moves the
    solved shape the way it should."""
    campaign_path = write_campaign(tmp_path, bridle=1.0)
    # The collapse factor (on the program write_campaign compiled): weaker wrinkling and
    # collapse moments let the loaded node sink further along gravity (+z).
    campaign = fitting.read_campaign(campaign_path)
    solver, case = fitting.CaseSolver(campaign), campaign.case("centre")
    sunk = [solver.solve(case, fitting.KiteModel(bending_scale=BENDING, collapse_scale=c))
            for c in (1.0, 0.2)]
    assert all(s.converged for s in sunk)
    node = case.loads[0].node
    assert sunk[1].positions[node, 2] - sunk[0].positions[node, 2] > 0.003
    assert run_diagnose(campaign_path, tmp_path / "out", "--held-out", "refit") == 0
    diagnosis = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert diagnosis["added"] == []
    assert diagnosis["verdict"].startswith("no candidate effect is missing")
    assert len(diagnosis["steps"]) == 1


USER_EFFECT = """
from fitting import ShapeEffect

def bridle_and_bending(campaign):
    return ShapeEffect("bridle_and_bending", ("rest_length_factors.bridle", "torsion_scale"),
                       ((0.9, 1.1), (0.5, 2.0)), "a user's pair")

WRONG = ShapeEffect("wrong", ("rest_length_factors.nowhere",), ((0.9, 1.1),))
"""


def test_candidate_effects_built_in_user_and_refused(tmp_path, capsys):
    """Built-in effects expand over the campaign's line sets with their plausible ranges; a
    user's function in a file is loaded (path relative to the campaign); an unknown effect or
    value is refused with the key and nothing is written."""
    write_mini_kite(tmp_path / "mini.npz")
    nodes = mini_kite_arrays()["initial_conditions_array"][:, :3]
    rows = "".join(f"{g},{k},{x:.17g},{y:.17g},{z:.17g}\n" for g, members in
                   (("LE", range(1, 6)), ("strut0", (2, 6, 7)), ("strut1", (4, 8, 9)))
                   for k, (x, y, z) in enumerate(nodes[list(members)]))
    for name in ("centre", "strut0", "strut1"):
        (tmp_path / f"{name}.csv").write_text("group,idx_in_group,x_m,y_m,z_m\n" + rows)
    (tmp_path / "campaign.toml").write_text(CAMPAIGN.replace("{candidates}", '["bending"]'))
    (tmp_path / "user.py").write_text(USER_EFFECT)
    campaign = fitting.read_campaign(tmp_path / "campaign.toml")
    effects = fitting.shape_effects(campaign)
    assert set(effects) == {"bending", "torsion", "collapse", "pressure", "rest_length.bridle",
                            "stiffness.bridle", "bending.leading_edge", "bending.struts",
                            "point_mass.centre", "point_mass.knot", "suspension"}
    assert effects["rest_length.bridle"].bounds == {"rest_length_factors.bridle": (0.9, 1.1)}
    assert effects["point_mass.knot"].bounds == {"point_masses_kg.knot": (0.0, 2.0)}
    assert effects["pressure"].values == ("pressure_offset_bar",)
    # The first suspension point stays: moving both is a rigid motion.
    assert effects["suspension"].values == tuple(f"suspension_offsets_mm.12.{axis}"
                                                 for axis in "xyz")
    user = fitting.resolve_shape_effect("user.py:bridle_and_bending", campaign)
    assert user.values == ("rest_length_factors.bridle", "torsion_scale")
    for text, words in (("user.py:WRONG", "unknown value"), ("nothing", "unknown effect"),
                        ("user.py:absent", "no ShapeEffect")):
        with pytest.raises(ValueError, match=words):
            fitting.resolve_shape_effect(text, campaign)
    with pytest.raises(ValueError, match="one plausible range"):
        fitting.ShapeEffect("bad", ("torsion_scale",), ())
    with pytest.raises(ValueError, match="0 <= low < high"):
        fitting.ShapeEffect("bad", ("point_masses_kg.knot",), ((-1.0, 1.0),))
    capsys.readouterr()
    assert run_diagnose(tmp_path / "campaign.toml", tmp_path / "bad", "--effect",
                        "user.py:WRONG") == 2
    assert "--effect: effect 'user.py:WRONG': unknown value" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()
    model = fitting.with_values(fitting.KiteModel(bending_scale=0.5),
                                ("torsion_scale", "pressure_factor",
                                 "bending_class_factors.struts", "pressure_offset_bar",
                                 "point_masses_kg.knot", "suspension_offsets_mm.12.x"),
                                (2.0, 1.1, 3.0, 0.01, 0.7, 5.0))
    assert (model.torsion_scale, model.pressure_factor) == (2.0, 1.1)
    assert fitting.read_model_file(_model_json(tmp_path, model), campaign) == model
    # The values reach the parameters: the struts' bending law x 3 on top of the kite's
    # 0.5, the torsion law x 2 and the pressure x 1.1 + 0.01 bar on every tube, 0.7 kg's
    # weight on the knot (node 10) and suspension node 12 5 mm along x.
    case = campaign.case("centre")
    plain = fitting.import_campaign_case(campaign, case, fitting.KiteModel())
    changed = fitting.import_campaign_case(campaign, case, model)
    strut = np.asarray(["7" in n or "9" in n for n in changed.tube_names])
    assert strut.sum() == 2 and (~strut).sum() >= 1
    pressure = float(plain.params.pressure[0])
    bending = np.array([float(law.initial_stiffness(pressure, 0.05)
                              / plain_law.initial_stiffness(pressure, 0.05))
                        for law, plain_law in zip(changed.params.bending_laws,
                                                  plain.params.bending_laws)])
    assert bending == pytest.approx(np.where(strut, 1.5, 0.5))
    assert [float(law.factor) for law in changed.params.torsion_laws] == [2.0] * len(strut)
    assert np.asarray(changed.params.pressure) == pytest.approx(
        1.1 * np.asarray(plain.params.pressure) + 1e3)
    knot = int(changed.node_index[10])
    np.testing.assert_allclose(
        jt.node_dead_load(changed.structure, changed.params, knot)
        - jt.node_dead_load(plain.structure, plain.params, knot), [0, 0, 0.7 * 9.81])
    moved = np.asarray(changed.params.elements.point_position) - np.asarray(
        plain.params.elements.point_position)
    expected = np.zeros_like(moved)
    expected[int(changed.node_index[12]) - changed.structure.node_count, 0] = 0.005
    np.testing.assert_allclose(moved, expected, atol=1e-15)


def _model_json(folder, model):
    path = folder / "model.json"
    path.write_text(json.dumps({"model": model.to_json()}))
    return path
