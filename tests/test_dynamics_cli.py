"""The dynamics on the command line: a spec's [dynamics] table in `jaxtube simulate`
(history.csv, figures, GIF, modes.csv), `jaxtube modes`, and [dynamics] errors."""

import csv
import json

import numpy as np
import pytest

import jaxtube as jt
from fitting._cli import main
from jaxtube._spec.load import parse_spec

SPEC = "tests/data/dynamics_cantilever.toml"


@pytest.mark.slow  # three compilations (equilibrium, modes, the time loop): ~1.5 min CPU
def test_simulate_with_a_dynamics_table_writes_the_history(tmp_path):
    code = main(["simulate", SPEC, "--out", str(tmp_path), "--quiet"])
    assert code == 0
    for name in ("history.csv", "history.png", "response.gif", "modes.csv", "summary.json"):
        assert (tmp_path / name).stat().st_size > 0, name
    with open(tmp_path / "history.csv") as file:
        rows = list(csv.DictReader(file))
    assert len(rows) == 25 and float(rows[-1]["time_s"]) == pytest.approx(0.1)
    assert all(row["converged"] == "1" for row in rows)
    dz = np.array([float(row["node_dz_mm"]) for row in rows])
    # A step load overshoots the static tip deflection P L^3 / (3 EI) towards twice it.
    static_mm = 1e3 * 1.0 / (3 * 300.0)
    assert dz.min() < -1.3 * static_mm and dz.min() > -2.2 * static_mm
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["converged_steps"] == 25 and summary["failed_steps"] == []

    modes_dir = tmp_path / "modes"
    assert main(["modes", SPEC, "--out", str(modes_dir), "--count", "4", "--quiet"]) == 0
    with open(modes_dir / "modes.csv") as file:
        modes = list(csv.DictReader(file))
    assert [row["mode"] for row in modes] == ["1", "2", "3", "4"]
    assert all(row["kind"] == "elastic" for row in modes)
    assert (modes_dir / "mode_shapes.png").stat().st_size > 0


def test_dynamics_table_errors_name_the_key():
    text = open(SPEC).read().replace("time_step_s = 0.004", "time_step_s = -1").replace(
        "modes = 4", 'load_history = "ramp"')
    with pytest.raises(jt.SpecError) as error:
        parse_spec(text, source="spec.toml")
    message = str(error.value)
    assert "dynamics.time_step_s" in message and "positive number" in message
    assert "dynamics.ramp_s" in message
