"""``fitting.sweep_on_cluster`` and ``jaxtube sweep --scheduler``: the grid cut into blocks on
a local Dask cluster of two workers (threads of this process, so the chunk program compiled
for the one-process sweep serves them) gives the one-process sweep point for point."""

import json

import numpy as np
import pytest
from distributed import LocalCluster

import fitting as ft
import jaxtube as jt
from fitting import SweepSettings, sweep
from fitting._cli import main

SETTINGS = SweepSettings(chunk_size=2)
WALL = 150e3  # E t [N/m]
GRID = np.meshgrid([0.2e5, 0.4e5], [0.06, 0.09], [1.0, 1.5], indexing="ij")
TIP_LOAD = 6.0


@pytest.fixture(scope="module")
def cluster():
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                      dashboard_address=":0") as local:
        yield local


@pytest.fixture(scope="module")
def one_process():
    return sweep(jt.TensionFieldLaw(WALL), *GRID, TIP_LOAD, SETTINGS)


def test_blocks_on_two_workers_give_the_one_process_sweep(cluster, one_process):
    with ft.open_cluster_client(cluster.scheduler_address) as client:
        spread = ft.sweep_on_cluster(client, jt.TensionFieldLaw(WALL), *GRID, TIP_LOAD,
                                     SETTINGS, blocks=4)
        with pytest.raises(ValueError, match="radius must be positive"):
            ft.sweep_on_cluster(client, jt.TensionFieldLaw(WALL), 0.2e5, 0.0, 1.0, TIP_LOAD)
    assert spread.pressure.shape == GRID[0].shape and spread.devices == 4
    for name in ft._sweep.cluster.POINT_FIELDS:
        np.testing.assert_array_equal(getattr(spread, name), getattr(one_process, name),
                                      err_msg=name)


def test_cli_sweeps_on_a_scheduler(cluster, one_process, tmp_path, capsys):
    out = tmp_path / "sweep"
    code = main(["sweep", "--law", "tension_field", "--wall-modulus-N-per-m", str(WALL),
                 "--pressure-bar", "0.2:0.4:2", "--radius-mm", "60:90:2", "--length-m",
                 "1:1.5:2", "--tip-load-N", str(TIP_LOAD), "--chunk-size", "2", "--quiet",
                 "--scheduler", cluster.scheduler_address, "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    assert json.loads((out / "summary.json").read_text())["points"] == 8
    rows = np.genfromtxt(out / "sweep.csv", delimiter=",", names=True, dtype=None,
                         encoding="utf-8")
    np.testing.assert_allclose(rows["collapse_load_N"], one_process.collapse_load.reshape(-1),
                               rtol=1e-9)  # the CSV keeps 10 digits
