"""The one table reader: the same messages for every file the workbench reads, and marker or
node coordinates that are finite and at most 1 km (no ``Infinity`` reaches a score file)."""

import re
from pathlib import Path

import pytest

import fitting
from fitting._cli import main

MEASUREMENT_HEADER = "curve,setup,pressure_bar,radius_m,length_m,deflection_mm,force_N"
READERS = {  # loader, a valid header, a valid row, the kind the message names
    "measurement": (fitting.load_measurements, MEASUREMENT_HEADER,
                    "a,cantilever_tip,0.15,0.075,0.6,1.5,2.0"),
    "marker": (fitting.load_markers, "group,idx_in_group,x_m,y_m,z_m", "LE,0,1,2,3"),
    "positions": (fitting.load_positions, "node,x_m,y_m,z_m", "0,1,2,3"),
    "tubes": (fitting.load_tubes, "group,node_1,node_2,radius_m", "LE,0,1,0.1"),
    "triangles": (fitting.load_triangles, "node_1,node_2,node_3", "0,1,2"),
}


def problems(path, load):
    with pytest.raises(fitting.DataError) as raised:
        load(path)
    return raised.value


@pytest.mark.parametrize("kind", list(READERS))
def test_every_file_kind_gives_the_same_messages(tmp_path, kind):
    load, header, row = READERS[kind]
    cases = {  # text -> (line, column, message)
        "": (1, None, "the file is empty; expected a header line such as"),
        header + "\n": (2, None, "expected at least one data row after the header, found none"),
        f"{header}\n{row},9\n": (2, None, f"expected {header.count(',') + 1} fields as in the "
                                          f"header, found {header.count(',') + 2}"),
        f"{header}\n{row}\n".encode() + b"\xe9\n": (3, None, "expected UTF-8 text, found byte "
                                                            "0xe9"),
        f"{header},{header.split(',')[-1]}\n{row},1\n": (1, header.split(",")[-1],
                                                         "expected each column once"),
    }
    for number, (text, (line, column, message)) in enumerate(cases.items()):
        path = tmp_path / f"bad{number}.csv"
        path.write_bytes(text if isinstance(text, bytes) else text.encode())
        error = problems(path, load)
        assert isinstance(error, ValueError) and error.kind == kind
        assert any((p.line, p.column) == (line, column) and message in p.message
                   for p in error.problems), str(error)
        assert str(error).splitlines()[0].endswith(f"in {kind} file {path}:")
        assert f"{path}:{line}: " in str(error)
    with pytest.raises(FileNotFoundError):
        load(tmp_path / "nowhere.csv")


def test_one_error_class_for_all_table_files():
    assert fitting.ShapeFileError is fitting.DataError
    assert fitting.ShapeFileProblem is fitting.DataProblem


@pytest.mark.parametrize("load, header, row, column, expected", [
    (fitting.load_markers, "group,idx_in_group,x_m,y_m,z_m", "LE,1,1e300,2,3", "x_m",
     "expected a coordinate of at most 1000 m in magnitude, found '1e300'"),
    (fitting.load_markers, "group,idx_in_group,x_mm,y_mm,z_mm", "LE,1,1,-2e6,3", "y_mm",
     "expected a coordinate of at most 1e+06 mm in magnitude, found '-2e6'"),
    (fitting.load_markers, "group,idx_in_group,x,y,z", "LE,1,1,2,Infinity", "z",
     "expected a finite number, found 'Infinity'"),
    (fitting.load_markers, "group,idx_in_group,x_m,y_m,z_m", "LE,1,1,1e999,3", "y_m",
     "expected a finite number, found '1e999' (overflows)"),
    (fitting.load_positions, "node,x_m,y_m,z_m", "1,1,2,-1001", "z_m",
     "expected a coordinate of at most 1000 m"),
])
def test_coordinates_must_be_finite_and_at_most_a_kilometre(tmp_path, load, header, row, column,
                                                           expected):
    path = tmp_path / "far.csv"
    first = "LE,0,0,0,0" if "group" in header else "0,0,0,0"
    path.write_text(f"{header}\n{first}\n{row}\n")
    error = problems(path, load)
    assert [(p.line, p.column) for p in error.problems] == [(3, column)]
    assert expected in error.problems[0].message
    assert f"{path}:3: column {column!r}: {expected}" in str(error)


def test_a_kilometre_is_accepted(tmp_path):
    path = tmp_path / "markers.csv"
    path.write_text("group,idx_in_group,x_m,y_m,z_m\nLE,0,-1000,0,1e3\n")
    assert fitting.load_markers(path).position.tolist() == [[-1000.0, 0.0, 1000.0]]
    path.write_text("node,x_mm,y_mm,z_mm\n0,1e6,0,0\n")
    assert fitting.load_positions(path).tolist() == [[1000.0, 0.0, 0.0]]


def test_score_shape_refuses_a_far_marker_and_writes_nothing(tmp_path, capsys):
    (tmp_path / "markers.csv").write_text("group,idx_in_group,x_m,y_m,z_m\nLE,0,1e300,0,0\n")
    (tmp_path / "positions.csv").write_text("node,x_m,y_m,z_m\n0,0,0,0\n1,1,0,0\n")
    (tmp_path / "tubes.csv").write_text("group,node_1,node_2,radius_m\nLE,0,1,0.1\n")
    out = tmp_path / "out"
    code = main(["--no-compilation-cache", "score-shape", "--markers",
                 str(tmp_path / "markers.csv"), "--positions", str(tmp_path / "positions.csv"),
                 "--tubes", str(tmp_path / "tubes.csv"), "--out", str(out)])
    assert code == 2 and not out.exists()
    assert f"{tmp_path / 'markers.csv'}:2: column 'x_m': expected a coordinate" in \
        capsys.readouterr().err


def test_every_csv_the_workbench_reads_goes_through_the_one_reader():
    """No other CSV parser in the packages: one set of messages for every table file."""
    root = Path(fitting.__file__).parents[1]
    readers = [str(path.relative_to(root)) for package in ("fitting", "jaxtube")
               for path in (root / package).rglob("*.py")
               if re.search(r"csv\.(reader|DictReader)|loadtxt|genfromtxt", path.read_text())]
    assert readers == ["fitting/_tables.py"]
