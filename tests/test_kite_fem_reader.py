"""The kite_fem reader: counts and mass of the bundled V3 model, and clear errors on broken
copies (file, key, row and column named). No solver is compiled here."""

from pathlib import Path

import numpy as np
import pytest

import jaxtube as jt

V3_MODEL = (Path(__file__).parents[1] / "experiments" / "data" / "v3_hanging" / "kite_fem"
            / "initial.npz")


def test_v3_counts_and_mass():
    model = jt.read_kite_fem(V3_MODEL)
    assert model.node_position.shape == (247, 3)
    assert model.beam_nodes.shape == (88, 2)
    assert model.spring_nodes.shape == (664, 2)
    assert model.pulley_nodes.shape == (14, 3)
    assert model.total_mass == pytest.approx(12.859, abs=5e-4)
    assert set(model.spring_kind) == {"noncompressive"}
    assert model.element_free_nodes().tolist() == [0, 72, 81, 106, 115, 127, 128, 129]
    assert np.flatnonzero(model.node_fixed).tolist() == [0]
    assert np.all(model.beam_pressure_bar == 0.25)
    # Rest lengths of the beams are their reference lengths in this file.
    length = np.linalg.norm(np.diff(model.node_position[model.beam_nodes], axis=1)[:, 0], axis=1)
    np.testing.assert_allclose(model.beam_rest_length, length, rtol=1e-9)
    with pytest.raises(ValueError):
        model.node_position[0, 0] = 1.0  # read-only record


def _broken_copy(tmp_path, edit) -> Path:
    with np.load(V3_MODEL) as archive:
        arrays = {key: archive[key] for key in archive.files}
    edit(arrays)
    path = tmp_path / "broken.npz"
    np.savez(path, **arrays)
    return path


def _set(key, row, column, value):
    def edit(arrays):
        array = arrays[key].copy()
        array[row, column] = value
        arrays[key] = array
    return edit


def _drop(key):
    def edit(arrays):
        del arrays[key]
    return edit


def _reshape(key):
    def edit(arrays):
        arrays[key] = arrays[key][:, :-1]
    return edit


@pytest.mark.parametrize("edit, words", [
    (_drop("beam_matrix"), ["'beam_matrix'", "missing"]),
    (_reshape("spring_matrix"), ["'spring_matrix'", "expected shape [rows, 6]", "[664, 5]"]),
    (_set("beam_matrix", 5, 1, 400), ["'beam_matrix'", "row 5", "column 1", "node 400",
                                      "out of range", "0..246"]),
    (_set("beam_matrix", 7, 2, 0.0), ["'beam_matrix'", "row 7", "column 2", "diameter",
                                      "positive"]),
    (_set("beam_matrix", 3, 3, -0.1), ["row 3", "column 3", "pressure [bar]", "positive"]),
    (_set("spring_matrix", 12, 5, "elastic"), ["'spring_matrix'", "row 12", "column 5",
                                               "unknown spring kind 'elastic'",
                                               "noncompressive"]),
    (_set("spring_matrix", 9, 2, "stiff"), ["row 9", "column 2", "stiffness", "a number",
                                            "'stiff'"]),
    (_set("spring_matrix", 4, 1, "3.5"), ["row 4", "column 1", "node index", "3.5"]),
    (_set("pulley_matrix", 2, 1, -1), ["'pulley_matrix'", "row 2", "column 1", "pulley node",
                                       "node -1"]),
    (_set("pulley_matrix", 0, 5, 0.0), ["row 0", "column 5", "rest length", "positive"]),
    (_set("initial_conditions_array", 17, 6, -0.5), ["'initial_conditions_array'", "row 17",
                                                     "column 6", "mass", "non-negative"]),
    (_set("initial_conditions_array", 3, 1, np.nan), ["row 3", "column 1", "y [m]", "finite"]),
    (_set("beam_matrix", 0, 1, 1), ["'beam_matrix'", "row 0", "to itself"]),
])
def test_errors_name_file_key_row_column(tmp_path, edit, words):
    path = _broken_copy(tmp_path, edit)
    with pytest.raises(jt.KiteFemFormatError) as info:
        jt.read_kite_fem(path)
    message = str(info.value)
    assert str(path) in message
    for word in words:
        assert word in message, (word, message)


def test_not_an_archive_and_missing_file(tmp_path):
    text = tmp_path / "model.npz"
    text.write_text("node,x\n")
    with pytest.raises(jt.KiteFemFormatError, match="not a NumPy .npz archive"):
        jt.read_kite_fem(text)
    with pytest.raises(FileNotFoundError, match="no such kite_fem model file"):
        jt.read_kite_fem(tmp_path / "absent.npz")


def test_solved_state_positions():
    state = V3_MODEL.parent / "states" / "load_case_1.npz"
    positions = jt.read_kite_fem_positions(state, node_count=247)
    assert positions.shape == (247, 3)
    # Suspension points 82 and 116 held where the model has them.
    model = jt.read_kite_fem(V3_MODEL)
    np.testing.assert_allclose(positions[[82, 116]], model.node_position[[82, 116]], atol=1e-9)


def test_cli_refuses_bad_kite_fem_input(tmp_path, capsys):
    from fitting._cli.main import main

    out = tmp_path / "out"
    path = _broken_copy(tmp_path, _set("spring_matrix", 12, 5, "elastic"))
    assert main(["simulate", "--kite-fem", str(path), "--out", str(out)]) == 2
    assert "row 12, column 5 (kind): unknown spring kind 'elastic'" in capsys.readouterr().err
    assert main(["simulate", "--out", str(out)]) == 2
    assert "give either a spec file or --kite-fem" in capsys.readouterr().err
    assert not out.exists()  # nothing written
