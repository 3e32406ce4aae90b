"""Campaign files: what a valid one reads as, and every refusal (file, key, reason; the
command writes nothing). No solve here: the V3 campaign solved is tested in
``tests/test_v3_hanging.py``.

Data: experiments/data/v3_hanging ("Structural model data from awegroup/kite_fem (MIT, (c)
2025 Patrick Roeleveld); marker data from pimjhaanen/photogrammetry_thesis (MIT, (c) 2026
PJ Haanen)").
"""

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

import fitting
import jaxtube as jt
from fitting._cli.shape import add_shape

DATA = Path(__file__).resolve().parents[1] / "experiments" / "data" / "v3_hanging"
CAMPAIGN = DATA / "campaign.toml"

VALID = f"""
[structure]
kite_fem = "{DATA / 'kite_fem' / 'initial.npz'}"
suspension = [82, 116]

[line_sets]
trailing_edge = [2, 4, 6]

[tubes]
LE = [1, 57]
strut0 = [7, 8]

[[cases]]
name = "hung"
pressure_bar = 0.15
markers = "{DATA / 'markers' / 'P1_S.csv'}"

[[cases]]
name = "tips"
pressure_bar = 0.25
loads = [{{node = 2, mass_kg = 2.0, direction = [0, 1, 0]}}]
"""


def write(tmp_path, text, name="campaign.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_v3_campaign_reads_with_its_ten_cases_routes_and_lengths():
    campaign = fitting.read_campaign(CAMPAIGN)
    names = [case.name for case in campaign.cases]
    assert names == [f"P{p}_{c}" for p in (1, 2) for c in ("S", "PL1", "PL2", "TL1", "TL2")]
    assert [c.role for c in campaign.cases] == ["calibrate"] * 5 + ["predict"] * 5
    assert [c.route for c in campaign.cases[:5]] == ["gravity", "drive", "drive", "stages",
                                                     "stages"]
    assert all(c.markers is None for c in campaign.cases[5:])
    centre = campaign.case("P2_PL2").loads[0]
    assert centre.node == 29 and centre.mass_along_gravity
    np.testing.assert_allclose(centre.force_N, [0.0, 0.0, 25.2 * 9.81])
    tips = campaign.case("P1_TL2").loads
    np.testing.assert_allclose([load.force_N for load in tips],
                               [[0, 5 * 9.81, 0], [0, -5 * 9.81, 0]])
    assert campaign.case("P1_TL1").measured_lengths_m["b"] == pytest.approx(7.843)
    assert len(campaign.line_sets["trailing_edge"]) == 28
    # The marker groups' tubes: the leading edge's 28 beams and each strut's 6.
    assert len(campaign.tubes["LE"]) == 28 and len(campaign.tubes["strut3"]) == 6
    assert campaign.tubes["strut3"][0][0] == 25 and campaign.tubes["strut3"][-1][1] == 26


def test_line_set_factor_scales_its_lines_alone():
    """The trailing edge's factor acts on the 28 springs joining neighbouring trailing-edge
    nodes (kite_fem's even wing nodes 2, 4, ..., 58) and on no other line."""
    campaign = fitting.read_campaign(CAMPAIGN)
    case = campaign.case("P1_S")
    plain = fitting.import_campaign_case(campaign, case, fitting.KiteModel())
    rows = fitting.line_set_rows(campaign, "trailing_edge")
    nodes = np.sort(campaign.kite_fem.spring_nodes[rows], axis=1)
    assert sorted(map(tuple, nodes.tolist())) == [(n, n + 2) for n in range(2, 58, 2)]
    before = np.asarray(plain.params.elements.line_rest_length)
    scaled = fitting.with_model_values(campaign, plain.params, fitting.KiteModel(
        rest_length_factors={"trailing_edge": 0.9}))
    after = np.asarray(scaled.elements.line_rest_length)
    others = np.setdiff1d(np.arange(before.size), rows)
    np.testing.assert_array_equal(after[others], before[others])
    np.testing.assert_allclose(after[rows], 0.9 * before[rows], rtol=1e-15)
    stiffer = fitting.with_model_values(campaign, plain.params, fitting.KiteModel(
        stiffness_factors={"trailing_edge": 2.0})).elements
    stiffness = np.asarray(plain.params.elements.line_stiffness)
    np.testing.assert_array_equal(np.asarray(stiffer.line_stiffness)[others], stiffness[others])
    np.testing.assert_allclose(np.asarray(stiffer.line_stiffness)[rows], 2 * stiffness[rows])
    np.testing.assert_array_equal(np.asarray(stiffer.line_rest_length), before)
    # The bending and collapse factors reach every tube's law, in the form asked for: the
    # initial stiffness x the bending factor in both forms, the plateau (wrinkling and
    # collapse moments) x the collapse factor, and in the moment form x the bending too.
    base = jt.EmpiricalBendingLaw2011()
    pressure, radius = 0.15e5, 0.08
    plateau = base.moment(1e4, pressure, radius)
    for form, collapse, moments in (("curvature", 0.6, 0.6), ("moment", 0.6, 0.18)):
        laws = fitting.import_campaign_case(campaign, case, fitting.KiteModel(
            law_form=form, bending_scale=0.3, collapse_scale=collapse)).params.bending_laws
        for law in laws[:3]:
            assert float(law.initial_stiffness(pressure, radius)) == pytest.approx(
                0.3 * float(base.initial_stiffness(pressure, radius)), rel=1e-12)
            assert float(law.moment(1e4, pressure, radius)) == pytest.approx(
                moments * float(plateau), rel=1e-6)


@pytest.mark.parametrize("change, key, reason", [
    (("[1, 57]", "[1, 300]"), "tubes.LE", "expected a node of the model"),
    (("[7, 8]", "[7, 4]"), "tubes.strut0", "no chain of beams joins nodes 7 and 4"),
    (("[2, 4, 6]", "[2, 4, 7]"), "line_sets.trailing_edge", "no line of the model joins "
                                                            "nodes 4 and 7"),
    (("P1_S.csv", "P9.csv"), "cases[0] (hung).markers", "marker file not found"),
    (("pressure_bar = 0.25", "pressure_bar = -0.25"), "cases[1] (tips).pressure_bar",
     "expected a positive number"),
    (("mass_kg = 2.0", "mass_kg = -2.0"), "cases[1] (tips).loads[0].mass_kg",
     "expected a number >= 0"),
    (("node = 2,", "node = 0,"), "cases[1] (tips).loads[0].node", "node 0 is held or fixed"),
    (("name = \"tips\"", "name = \"tips\"\nrole = \"calibrate\""), "cases[1] (tips).role",
     "a calibration case needs markers"),
    (("[line_sets]", "[model]\nstrut_stiffness = 2.0\n\n[line_sets]"),
     "model.strut_stiffness", "unknown effect"),
    (("[line_sets]", "[model.rest_length_factors]\nbridle = 0.9\n\n[line_sets]"),
     "model.rest_length_factors.bridle", "unknown line set"),
    (("[line_sets]", "[points]\nknot = 0\n\n[line_sets]"), "points.knot",
     "node 0 is held or fixed"),
    (("[line_sets]", "[points]\ncentre = 29\n\n[model.point_masses_kg]\ncentre = -1.0\n\n"
                     "[line_sets]"), "model.point_masses_kg.centre", "expected a number >= 0"),
])
def test_campaign_errors_name_file_key_and_reason_and_nothing_is_written(tmp_path, change,
                                                                           key, reason):
    old, new = change
    assert old in VALID
    path = write(tmp_path, VALID.replace(old, new, 1))
    with pytest.raises(fitting.CampaignError) as raised:
        fitting.read_campaign(path)
    message = str(raised.value)
    assert f"{path}: {key}: " in message and reason in message, message
    parser = argparse.ArgumentParser()
    add_shape(parser.add_subparsers())
    for command in ("compare", "predict"):
        args = parser.parse_args(["shape", command, str(path), "--out", str(tmp_path / command)])
        assert args.run(args) == 2
        assert not (tmp_path / command).exists()


def test_every_problem_at_once_and_model_file_checked(tmp_path):
    path = write(tmp_path, VALID.replace("[1, 57]", "[1, 300]").replace(
        "pressure_bar = 0.25", "pressure_bar = 0"))
    with pytest.raises(fitting.CampaignError) as raised:
        fitting.read_campaign(path)
    assert len(raised.value.problems) == 2
    campaign = fitting.read_campaign(write(tmp_path, VALID, "ok.toml"))
    assert [c.role for c in campaign.cases] == ["calibrate", "predict"]
    model = tmp_path / "model.json"
    model.write_text(json.dumps({"model": {"bending_scale": 0.5,
                                           "rest_length_factors": {"trailing_edge": 0.95}}}))
    assert fitting.read_model_file(model, campaign) == fitting.KiteModel(
        "curvature", 0.5, {"trailing_edge": 0.95})
    model.write_text(json.dumps({"model": {"pressure_offset_bar": -0.01, "collapse_scale": 0.6,
                                           "suspension_offsets_mm": {"116.z": 4.0}}}))
    assert fitting.read_model_file(model, campaign) == fitting.KiteModel(
        pressure_offset_bar=-0.01, suspension_offsets_mm={"116.z": 4.0}, collapse_scale=0.6)
    for table, words in (({"bending_scale": -1}, "model.bending_scale: expected a positive"),
                         ({"collapse_scale": 0}, "model.collapse_scale: expected a positive"),
                         ({"suspension_offsets_mm": {"82.w": 1.0}},
                          "model.suspension_offsets_mm.82.w: unknown suspension axis")):
        model.write_text(json.dumps({"model": table}))
        with pytest.raises(fitting.CampaignError, match=words):
            fitting.read_model_file(model, campaign)


def test_measured_lengths_are_read_by_the_table_reader(tmp_path):
    """The lengths file goes through the workbench's one table reader: a length that is not a
    positive number is refused naming the file, the line and the column."""
    lengths = tmp_path / "lengths.csv"
    lengths.write_text("case,b\nhung,4.5\ntips,-1\n")
    text = VALID.replace("[[cases]]", f'[lengths]\nfile = "{lengths}"\n\n[lengths.pairs]\n'
                                      f'b = [2, 58]\n\n[[cases]]', 1)
    text = text.replace('name = "hung"', 'name = "hung"\nlengths_row = "hung"')
    lengths.write_text("case,b\nhung,4.5\ntips,4.7\n")
    campaign = fitting.read_campaign(write(tmp_path, text))
    assert campaign.case("hung").measured_lengths_m == {"b": 4.5}
    lengths.write_text("case,b\nhung,4.5\ntips,-1\n")
    with pytest.raises(fitting.CampaignError) as raised:
        fitting.read_campaign(write(tmp_path, text))
    assert f"{lengths}:3: column 'b': expected a positive length [m], found '-1'" in \
        str(raised.value)
