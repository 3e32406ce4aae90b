"""Loading measured force-deflection curves: conversion to SI, validation, round trip."""

import csv
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fitting import DataError, DataProblem, MeasuredCurve, MeasuredData, load_measurements

SHARED = Path(__file__).parent / "data" / "cantilever_shear.csv"
HEADER = "curve,setup,pressure_bar,radius_m,length_m,deflection_mm,force_N"
GOOD_ROWS = [
    "a,cantilever_tip,0.15,0.075,0.6,1.5,2.0",
    "a,cantilever_tip,0.15,0.075,0.6,3.0,4.0",
]


def write(tmp_path, lines, name="data.csv"):
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def problems_of(path):
    with pytest.raises(DataError) as info:
        load_measurements(path)
    error = info.value
    assert isinstance(error, ValueError)
    # Every problem names the file, its line and (where there is one) its column.
    for problem in error.problems:
        assert isinstance(problem, DataProblem)
        assert str(path) in str(problem)
        assert str(problem) in str(error)
    return error.problems


def only_problem(path, line, column, *fragments):
    problems = problems_of(path)
    assert len(problems) == 1, "\n".join(map(str, problems))
    (problem,) = problems
    assert (problem.line, problem.column) == (line, column), str(problem)
    text = str(problem)
    assert f"{path}:{line}" in text
    if column is not None:
        assert repr(column) in text
    for fragment in fragments:
        assert fragment in text, text
    return problem


# ------------------------------------------------------------------ the shared file


def test_shared_file_in_si_units():
    data = load_measurements(SHARED)
    assert data.source == SHARED
    assert len(data.curves) == 6
    assert data.point_count == 150
    assert [curve.name for curve in data] == [f"shear-{i}" for i in range(1, 7)]
    np.testing.assert_array_equal(data.pressures(), [15000.0, 25000.0, 35000.0])
    np.testing.assert_array_equal(data.radii(), [0.075])
    np.testing.assert_array_equal(data.lengths(), [0.6, 1.2])

    first = data["shear-1"]
    assert first.setup == "cantilever_tip" and first.setup_kind == "cantilever_tip"
    assert (first.pressure, first.radius, first.length) == (15000.0, 0.075, 0.6)
    # First data line of the file: shear-1,...,1.725,1.7114
    assert first.row_numbers[0] == 2
    assert first.deflection[0] == 0.001725
    assert first.force[0] == 1.7114

    with SHARED.open(newline="") as file:
        table = list(csv.DictReader(file))
    for curve in data:
        assert curve.point_count == 25
        assert curve.deflection.dtype == np.float64 and curve.force.dtype == np.float64
        assert np.all(np.diff(curve.deflection) >= 0)
        np.testing.assert_array_equal(curve.weight, np.ones(25))
        # Each point matches its source line, converted (mm -> m).
        for deflection, force, line in zip(curve.deflection, curve.force, curve.row_numbers):
            row = table[line - 2]
            assert row["curve"] == curve.name
            assert deflection == pytest.approx(float(row["deflection_mm"]) / 1000, rel=1e-15)
            assert force == float(row["force_N"])
            assert curve.pressure == pytest.approx(float(row["pressure_bar"]) * 1e5, rel=1e-15)


def test_result_is_immutable():
    data = load_measurements(SHARED)
    curve = data.curves[0]
    with pytest.raises(ValueError):
        curve.deflection[0] = 1.0
    with pytest.raises(AttributeError):
        curve.pressure = 1.0
    with pytest.raises(AttributeError):
        data.curves = ()


# ------------------------------------------------------------------ units


def test_unit_variants_give_identical_si_values(tmp_path):
    reference = load_measurements(write(tmp_path, [HEADER, *GOOD_ROWS], "reference.csv"))
    variants = {
        "kPa_mm_kN": (
            "curve,setup,pressure_kPa,radius_mm,length_mm,deflection_m,force_kN",
            ["a,cantilever_tip,15,75,600,0.0015,0.002", "a,cantilever_tip,15,75,600,0.003,0.004"],
        ),
        "Pa_reordered": (
            "force_N,deflection_mm,length_m,radius_m,pressure_Pa,setup,curve",
            ["2.0,1.5,0.6,0.075,15000,cantilever_tip,a",
             "4.0,3.0,0.6,0.075,1.5e4,cantilever_tip,a"],
        ),
    }
    for name, (header, rows) in variants.items():
        data = load_measurements(write(tmp_path, [header, *rows], f"{name}.csv"))
        (curve,), (expected,) = data.curves, reference.curves
        for quantity in ("pressure", "radius", "length"):
            assert getattr(curve, quantity) == getattr(expected, quantity), (name, quantity)
        np.testing.assert_array_equal(curve.deflection, expected.deflection)
        np.testing.assert_array_equal(curve.force, expected.force)


def test_points_sorted_by_deflection_keeping_row_numbers(tmp_path):
    path = write(tmp_path, [
        HEADER + ",weight,note",
        "a,cantilever_tip,0.15,0.075,0.6,3.0,4.0,2,third",
        "a,cantilever_tip,0.15,0.075,0.6,-1.0,-1.0,1,pushed up",
        "b,cantilever_tip,0.25,0.075,1.2,0.5,0.1,1,",
        "a,cantilever_tip,0.15,0.075,0.6,1.0,2.0,0.5,",
        "a,cantilever_tip,0.15,0.075,0.6,1.0,2.5,1,repeat",
        "b,cantilever_tip,0.25,0.075,1.2,0.6,0.2,1,",
    ])
    data = load_measurements(path)
    assert [curve.name for curve in data] == ["a", "b"]
    a = data["a"]
    np.testing.assert_array_equal(a.deflection, [-0.001, 0.001, 0.001, 0.003])
    np.testing.assert_array_equal(a.force, [-1.0, 2.0, 2.5, 4.0])
    np.testing.assert_array_equal(a.weight, [1.0, 0.5, 1.0, 2.0])
    np.testing.assert_array_equal(a.row_numbers, [3, 5, 6, 2])
    assert a.notes == ("pushed up", "", "repeat", "third")
    np.testing.assert_array_equal(data["b"].row_numbers, [4, 7])


# ------------------------------------------------------------------ bad input, one at a time


def after_good_rows(row):
    """A file with two valid points of curve 'a' (lines 2-3), then ``row`` on line 4."""
    return [HEADER, *GOOD_ROWS, row]


def with_header(header, *rows):
    return [header, *rows]


@pytest.mark.parametrize(
    "lines, line, column, fragments",
    [
        # header problems (line 1)
        (with_header("curve,setup,pressure_psi,radius_m,length_m,deflection_mm,force_N",
                     *GOOD_ROWS),
         1, "pressure_psi", ["unknown unit 'psi'", "pressure_bar, pressure_kPa, pressure_Pa"]),
        (with_header("curve,setup,pressure_bar,radius_m,length_m,deflection_mm,force_lbf",
                     *GOOD_ROWS),
         1, "force_lbf", ["unknown unit 'lbf'", "force_N, force_kN"]),
        (with_header(HEADER + ",temperature", *(row + ",20" for row in GOOD_ROWS)),
         1, "temperature", ["unknown column 'temperature'", "weight and note"]),
        (with_header(HEADER + ",radius_mm", *(row + ",75" for row in GOOD_ROWS)),
         1, "radius_mm", ["exactly one column for radius", "radius_m, radius_mm"]),
        (with_header(HEADER + ",note,note", *(row + ",x,y" for row in GOOD_ROWS)),
         1, "note", ["more than once"]),
        (with_header("curve,setup,pressure_bar,radius_m,deflection_mm,force_N",
                     "a,cantilever_tip,0.15,0.075,1,1", "a,cantilever_tip,0.15,0.075,2,2"),
         1, None, ["missing column for length", "length_m, length_mm"]),
        (with_header("setup,pressure_bar,radius_m,length_m,deflection_mm,force_N",
                     "cantilever_tip,0.15,0.075,0.6,1,1"),
         1, None, ["missing column curve"]),
        # value problems (line 4)
        (after_good_rows("a,cantilever_tip,0.15,0.075,0.6,abc,9"), 4, "deflection_mm",
         ["expected a finite number", "'abc'"]),
        (after_good_rows("a,cantilever_tip,0.15,0.075,0.6,9,"), 4, "force_N",
         ["expected a finite number", "empty field"]),
        (after_good_rows("a,cantilever_tip,nan,0.075,0.6,9,9"), 4, "pressure_bar",
         ["expected a finite number", "'nan'"]),
        (after_good_rows("a,cantilever_tip,0.15,0.075,0.6,9,-inf"), 4, "force_N",
         ["expected a finite number", "'-inf'"]),
        (after_good_rows("a,cantilever_tip,0.15,0.075,0.6,1e999,9"), 4, "deflection_mm",
         ["expected a finite deflection", "'1e999'"]),
        (after_good_rows("a,cantilever_tip,-0.15,0.075,0.6,9,9"), 4, "pressure_bar",
         ["expected a positive pressure", "'-0.15'"]),
        (after_good_rows("a,cantilever_tip,0.15,0,0.6,9,9"), 4, "radius_m",
         ["expected a positive radius", "'0'"]),
        (after_good_rows("a,cantilever_tip,0.15,0.075,-1,9,9"), 4, "length_m",
         ["expected a positive length", "'-1'"]),
        (with_header(HEADER + ",weight", *(row + ",1" for row in GOOD_ROWS),
                     "a,cantilever_tip,0.15,0.075,0.6,9,9,-1"),
         4, "weight", ["expected a positive weight", "'-1'"]),
        (after_good_rows("a,bending,0.15,0.075,0.6,9,9"), 4, "setup",
         ["expected a known setup", "cantilever_tip", "'bending'"]),
        (after_good_rows("a,cantilever_tip:left,0.15,0.075,0.6,9,9"), 4, "setup",
         ["takes no arguments", "'left'"]),
        (after_good_rows("a,cantilever_tip,0.15,0.075,0.6,9"), 4, None,
         ["expected 7 fields", "found 6"]),
        # rows of one curve that disagree with its first row (line 2)
        (after_good_rows("a,cantilever_tip,0.25,0.075,0.6,9,9"), 4, "pressure_bar",
         ["curve 'a'", "line 2", "'0.15'", "'0.25'"]),
        (after_good_rows("a,cantilever_tip,0.15,0.08,0.6,9,9"), 4, "radius_m",
         ["curve 'a'", "line 2", "'0.075'", "'0.08'"]),
        (after_good_rows("a,cantilever_tip,0.15,0.075,1.2,9,9"), 4, "length_m",
         ["curve 'a'", "line 2", "'0.6'", "'1.2'"]),
    ],
)
def test_each_bad_input_names_file_line_and_column(tmp_path, lines, line, column, fragments):
    only_problem(write(tmp_path, lines), line, column, *fragments)


def test_disagreeing_setup_and_a_new_setup_kind(tmp_path, monkeypatch):
    # A new setup kind is one registry entry; rows of a curve must agree on the setup.
    from fitting._data import setups as _data

    kinds = {**_data._SETUP_KINDS, "three_point": _data._SetupKind("test", _data._no_arguments)}
    monkeypatch.setattr(_data, "_SETUP_KINDS", kinds)
    path = write(tmp_path, after_good_rows("a,three_point,0.15,0.075,0.6,9,9"))
    only_problem(path, 4, "setup", "curve 'a'", "line 2", "'cantilever_tip'", "'three_point'")
    path = write(tmp_path, [HEADER, *(row.replace("cantilever_tip", "three_point")
                                      for row in GOOD_ROWS)])
    assert load_measurements(path)["a"].setup == "three_point"


def test_empty_curve_name(tmp_path):
    path = write(tmp_path, [HEADER, *GOOD_ROWS, " ,cantilever_tip,0.15,0.075,0.6,9,9"])
    only_problem(path, 4, "curve", "expected a curve name", "empty field")


def test_curve_with_one_point(tmp_path):
    path = write(tmp_path, [HEADER, *GOOD_ROWS, "b,cantilever_tip,0.15,0.075,0.6,9,9"])
    only_problem(path, 4, "curve", "curve 'b'", "1 usable point", "at least 2")


def test_curve_without_usable_rows_is_an_empty_curve(tmp_path):
    path = write(tmp_path, [
        HEADER, *GOOD_ROWS,
        "b,cantilever_tip,0.15,0.075,0.6,x,9",
        "b,cantilever_tip,0.15,0.075,0.6,9,y",
    ])
    problems = problems_of(path)
    assert [(p.line, p.column) for p in problems] == [
        (4, "curve"), (4, "deflection_mm"), (5, "force_N"),
    ]
    assert "empty curve 'b'" in problems[0].message
    assert "2 rows" in problems[0].message


@pytest.mark.parametrize("content", ["", "\n\n", "   \n"])
def test_empty_file(tmp_path, content):
    path = tmp_path / "empty.csv"
    path.write_text(content)
    only_problem(path, 1, None, "the file is empty", HEADER)


def test_header_without_rows(tmp_path):
    only_problem(write(tmp_path, [HEADER]), 2, None, "at least one data row")


def test_not_utf8(tmp_path):
    path = tmp_path / "latin1.csv"
    path.write_bytes((HEADER + "\n" + GOOD_ROWS[0] + "\nb\xe9,x\n").encode("latin-1"))
    only_problem(path, 3, None, "expected UTF-8", "0xe9")


def test_byte_order_mark_and_blank_lines_are_accepted(tmp_path):
    path = tmp_path / "excel.csv"
    path.write_text("\ufeff" + HEADER + "\r\n" + GOOD_ROWS[0] + "\r\n\r\n" + GOOD_ROWS[1] + "\r\n",
                    encoding="utf-8")
    curve = load_measurements(path)["a"]
    np.testing.assert_array_equal(curve.row_numbers, [2, 4])


def test_duplicate_deflections_are_allowed(tmp_path):
    path = write(tmp_path, [HEADER, GOOD_ROWS[0], GOOD_ROWS[0], GOOD_ROWS[1]])
    np.testing.assert_array_equal(load_measurements(path)["a"].deflection, [0.0015, 0.0015, 0.003])


def test_missing_file_is_an_os_error(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_measurements(tmp_path / "nowhere.csv")


# ------------------------------------------------------------------ bad input, all together


def test_several_problems_reported_together_in_file_order(tmp_path):
    path = write(tmp_path, [
        "curve,setup,pressure_bar,radius_m,length_m,deflection_mm,force_N,extra",  # 1
        "a,cantilever_tip,0.15,0.075,0.6,1,2,",  # 2
        "a,cantilever_tip,0.2,0.075,0.6,abc,2,",  # 3: disagreeing pressure, non-numeric
        "a,cantilever_tip,0.15,-0.075,0.6,nan,1,",  # 4: bad radius, NaN deflection
        ",cantilever_tip,0.15,0.075,0.6,1,2,",  # 5: empty curve name
        "b,nowhere,0.15,0.075,0.6,1,2,",  # 6: unknown setup; b has no usable row
    ])
    problems = problems_of(path)
    assert [(p.line, p.column) for p in problems] == [
        (1, "extra"),
        (2, "curve"),  # curve 'a' has only one usable point (line 2)
        (3, "pressure_bar"),
        (3, "deflection_mm"),
        (4, "radius_m"),
        (4, "deflection_mm"),
        (5, "curve"),
        (6, "curve"),  # empty curve 'b'
        (6, "setup"),
    ]
    with pytest.raises(DataError) as info:
        load_measurements(path)
    message = str(info.value)
    assert message.splitlines()[0] == f"9 problems in measurement file {path}:"
    assert len(message.splitlines()) == 10


def test_long_problem_lists_are_shortened_in_the_message(tmp_path):
    path = write(tmp_path, [HEADER] + ["a,cantilever_tip,0.15,0.075,0.6,x,1"] * 150)
    with pytest.raises(DataError) as info:
        load_measurements(path)
    assert len(info.value.problems) == 151  # 150 bad values + the empty curve 'a'
    lines = str(info.value).splitlines()
    assert lines[0].startswith("151 problems") and lines[-1] == "  ... and 51 more (see .problems)"


# ------------------------------------------------------------------ writing


def test_round_trip_through_write_csv(tmp_path):
    data = load_measurements(SHARED)
    for units in [None, {"pressure": "kPa", "radius": "mm", "deflection": "m", "force": "kN"},
                  {"pressure": "Pa", "length": "mm"}]:
        path = data.write_csv(tmp_path / "copy.csv", units=units)
        again = load_measurements(path)
        assert [c.name for c in again] == [c.name for c in data]
        for original, copy in zip(data, again):
            assert copy.setup == original.setup
            for quantity in ("pressure", "radius", "length"):
                assert getattr(copy, quantity) == getattr(original, quantity)
            np.testing.assert_array_equal(copy.deflection, original.deflection)
            np.testing.assert_array_equal(copy.force, original.force)
            np.testing.assert_array_equal(copy.weight, original.weight)
    # Default units are those of the shared file; the values read the same.
    data.write_csv(tmp_path / "default.csv")
    with (tmp_path / "default.csv").open(newline="") as file:
        rows = list(csv.reader(file))
    assert ",".join(rows[0]) == HEADER
    assert rows[1] == ["shear-1", "cantilever_tip", "0.15", "0.075", "0.6", "1.725", "1.7114"]
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_write_csv_keeps_weights_and_notes(tmp_path):
    curve = MeasuredCurve(
        name="synthetic", setup="cantilever_tip", pressure=2.0e4, radius=0.05, length=1.0,
        deflection=[0.02, 0.01, -0.005], force=[2.0, 1.0, -0.5], weight=[1.0, 3.0, 0.5],
        notes=["", "a, quoted \"note\"", ""],
    )
    assert curve.row_numbers is None
    np.testing.assert_array_equal(curve.deflection, [-0.005, 0.01, 0.02])
    data = MeasuredData((curve,))
    rows = data.to_rows(units={"deflection": "m"})
    assert rows[0] == {"curve": "synthetic", "setup": "cantilever_tip", "pressure_bar": 0.2,
                       "radius_m": 0.05, "length_m": 1.0, "deflection_m": -0.005,
                       "force_N": -0.5, "weight": 0.5, "note": ""}
    again = load_measurements(data.write_csv(tmp_path / "synthetic.csv"))["synthetic"]
    np.testing.assert_array_equal(again.deflection, curve.deflection)
    np.testing.assert_array_equal(again.weight, curve.weight)
    assert again.notes == curve.notes
    np.testing.assert_array_equal(again.row_numbers, [2, 3, 4])  # written sorted


def test_write_csv_replaces_atomically(tmp_path, monkeypatch):
    data = load_measurements(SHARED)
    target = tmp_path / "out.csv"
    target.write_text("old contents\n")

    def broken_replace(source, destination):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(OSError, match="disk full"):
        data.write_csv(target)
    assert target.read_text() == "old contents\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv"]


def test_write_csv_rejects_unknown_units(tmp_path):
    data = load_measurements(SHARED)
    with pytest.raises(ValueError, match="accepted: bar, kPa, Pa"):
        data.write_csv(tmp_path / "x.csv", units={"pressure": "psi"})
    with pytest.raises(ValueError, match="unknown quantity"):
        data.to_rows(units={"temperature": "K"})
    assert list(tmp_path.iterdir()) == []


finite = st.floats(allow_nan=False, allow_infinity=False, min_value=-1e6, max_value=1e6)
positive = st.floats(min_value=1e-6, max_value=1e7, allow_subnormal=False)


@settings(max_examples=40, deadline=None)
@given(
    pressure=positive, radius=positive, length=positive,
    points=st.lists(st.tuples(finite, finite), min_size=2, max_size=5),
    units=st.fixed_dictionaries({
        "pressure": st.sampled_from(["bar", "kPa", "Pa"]),
        "radius": st.sampled_from(["m", "mm"]),
        "deflection": st.sampled_from(["mm", "m"]),
        "force": st.sampled_from(["N", "kN"]),
    }),
)
def test_round_trip_is_exact_in_any_units(tmp_path_factory, pressure, radius, length, points,
                                          units):
    deflection, force = zip(*points)
    curve = MeasuredCurve(name="c", setup="cantilever_tip", pressure=pressure, radius=radius,
                          length=length, deflection=deflection, force=force)
    path = MeasuredData((curve,)).write_csv(tmp_path_factory.mktemp("rt") / "c.csv", units)
    again = load_measurements(path)["c"]
    assert (again.pressure, again.radius, again.length) == (pressure, radius, length)
    np.testing.assert_array_equal(again.deflection, curve.deflection)
    np.testing.assert_array_equal(again.force, curve.force)


# ------------------------------------------------------------------ constructing directly


def test_constructor_checks():
    good = dict(name="c", setup="cantilever_tip", pressure=1e4, radius=0.05, length=1.0,
                deflection=[0.0, 0.01], force=[0.0, 1.0])
    MeasuredCurve(**good)
    for change, message in [
        ({"setup": "bending"}, "known setup"),
        ({"pressure": -1.0}, "pressure must be > 0"),
        ({"deflection": [0.0]}, "force has 2 entries"),
        ({"deflection": [0.0], "force": [1.0]}, "at least 2 points"),
        ({"force": [0.0, np.nan]}, "finite"),
        ({"weight": [1.0, 0.0]}, "positive"),
        ({"name": " "}, "non-empty"),
    ]:
        with pytest.raises(ValueError, match=message):
            MeasuredCurve(**{**good, **change})
    with pytest.raises(ValueError, match="unique"):
        MeasuredData((MeasuredCurve(**good), MeasuredCurve(**good)))
