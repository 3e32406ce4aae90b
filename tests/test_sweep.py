"""``fitting.sweep`` and ``jaxtube sweep``: agreement with single solves, sharding over
devices, the ``p r^3 / L`` scaling of the tension-field cantilever, and the command line.

Every sweep here uses the same settings and chunk shape (8 points), so the whole module
compiles the sweep once (plus one single-solve path for the comparison, and the sharded
program in a subprocess).
"""

import json
import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxtube as jt
from fitting import SweepSettings, sweep
from jaxtube._cli import main
from tests.helpers import with_tip_force

# Chunks of 2 points: the shape each of 4 devices gets of a sharded chunk of 8, so the
# sharded and the single-device runs execute the same per-device program.
SETTINGS = SweepSettings(chunk_size=2)
SOFT_WALL = 150e3  # E t [N/m] of a kite tube: visible geometric nonlinearity at collapse
STIFF_WALL = 5e6  # p L / (2 E t) <= 0.01: deflections small at collapse
# Eight specimens spanning 0.1-0.5 bar, r = 50-150 mm, L = 0.5-2 m.
PRESSURE = np.array([0.1, 0.2, 0.3, 0.5, 0.15, 0.4, 0.25, 0.5]) * 1e5
RADIUS = np.array([0.05, 0.075, 0.1, 0.15, 0.12, 0.06, 0.09, 0.05])
LENGTH = np.array([1.0, 1.0, 0.5, 2.0, 1.5, 0.8, 1.2, 0.5])
TIP_LOAD = 6.0  # [N]
REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def soft():
    return sweep(jt.TensionFieldLaw(SOFT_WALL), PRESSURE, RADIUS, LENGTH, TIP_LOAD, SETTINGS)


@pytest.fixture(scope="module")
def stiff():
    return sweep(jt.TensionFieldLaw(STIFF_WALL), PRESSURE, RADIUS, LENGTH, TIP_LOAD, SETTINGS)


def test_every_point_converges_and_reports(soft, stiff):
    for result in (soft, stiff):
        assert result.failed_count == 0, result.failure_reasons()
        assert np.all(result.failure_reasons() == "ok")
        assert np.all(np.isfinite(result.collapse_load))
        assert np.all(result.collapse_mismatch <= SETTINGS.moment_tolerance)
    # Comer & Levy moments and EI = pi E t r^3, exactly (the law's regime boundaries).
    np.testing.assert_allclose(soft.wrinkling_moment, math.pi * PRESSURE * RADIUS**3 / 2,
                               rtol=1e-12)
    np.testing.assert_allclose(soft.collapse_moment, 0.95 * math.pi * PRESSURE * RADIUS**3,
                               rtol=1e-12)
    np.testing.assert_allclose(soft.initial_stiffness, math.pi * SOFT_WALL * RADIUS**3,
                               rtol=1e-12)


@pytest.fixture(scope="module")
def single_solve():
    """One compiled static solve of a single, separately built cantilever under a dead tip
    load (from the unloaded shape, no load steps), shared by every comparison."""
    structure, params = jt.cantilever(1.0, 0.075, 2e4, SETTINGS.segments,
                                      jt.TensionFieldLaw(SOFT_WALL))
    tip = structure.node_id("tube:end")

    @jax.jit
    def solve(pressure, radius, length, load):
        p = eqx.tree_at(lambda q: (q.node_position, q.node_radius, q.pressure),
                        with_tip_force(structure, params, jnp.stack([0.0, 0.0, -load])),
                        (params.node_position * length,
                         jnp.full_like(params.node_radius, radius),
                         jnp.full_like(params.pressure, pressure)))
        sol = jt.equilibrium(structure, p, solver=SETTINGS.solver)
        return (sol.converged, jnp.linalg.norm(sol.joint_moment[0, :2]),
                params.node_position[tip, 2] * length - sol.node_position[tip, 2])

    return solve


@pytest.mark.parametrize("point", [0, 3, 6])
def test_sweep_agrees_with_single_solves(soft, single_solve, point):
    """At the sweep's loads, a separately built and solved cantilever has the law's
    wrinkling / collapse moment at its root, and the sweep's tip deflection."""
    p, r, length = PRESSURE[point], RADIUS[point], LENGTH[point]
    for load, moment in ((soft.wrinkling_load, math.pi * p * r**3 / 2),
                         (soft.collapse_load, 0.95 * math.pi * p * r**3)):
        converged, root_moment, _ = single_solve(p, r, length, load[point])
        assert bool(converged)
        np.testing.assert_allclose(root_moment, moment, rtol=2e-6)
    converged, _, deflection = single_solve(p, r, length, TIP_LOAD)
    assert bool(converged)
    np.testing.assert_allclose(soft.tip_deflection[point], deflection, rtol=1e-8)


SHARDED = textwrap.dedent("""
    import sys
    import numpy as np
    import jax
    import jaxtube as jt
    from fitting import SweepSettings, sweep
    assert len(jax.devices()) == 4, jax.devices()
    p, r, length, out = (np.load(sys.argv[1])[k] for k in ("p", "r", "length", "out"))
    result = sweep(jt.TensionFieldLaw(float(sys.argv[2])), p, r, length, float(sys.argv[3]),
                   SweepSettings(chunk_size=8))
    assert result.devices == 4 and result.settings.chunk_size == 8
    np.savez(str(out), **{k: getattr(result, k) for k in sys.argv[4].split(",")})
""")
COMPARED = ("wrinkling_load", "collapse_load", "tip_deflection", "initial_stiffness",
            "wrinkling_status", "collapse_status", "deflection_status", "iterations")


def test_sharded_over_four_host_devices_equals_single_device(soft, tmp_path):
    inputs = tmp_path / "inputs.npz"
    out = tmp_path / "sharded.npz"
    np.savez(inputs, p=PRESSURE, r=RADIUS, length=LENGTH, out=str(out))
    # Four forced host devices; keep the single-threaded kernels of tests/conftest.py.
    flags = os.environ.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=4"
    env = dict(os.environ, XLA_FLAGS=flags.strip(), JAX_PLATFORMS="cpu", PYTHONPATH=str(REPO))
    done = subprocess.run([sys.executable, "-c", SHARDED, str(inputs), str(SOFT_WALL),
                           str(TIP_LOAD), ",".join(COMPARED)], env=env, cwd=REPO,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    sharded = np.load(out)
    # Statuses and Newton step counts exactly; values to round-off (the partitioned program
    # fuses differently, measured differences about 1 ulp).
    for name in COMPARED:
        if sharded[name].dtype.kind in "iub":
            np.testing.assert_array_equal(sharded[name], getattr(soft, name), err_msg=name)
        else:
            np.testing.assert_allclose(sharded[name], getattr(soft, name), rtol=1e-13,
                                       atol=0, err_msg=name)


def test_cli_end_to_end_on_a_tiny_grid(tmp_path, capsys):
    out = tmp_path / "sweep"
    code = main(["sweep", "--law", "tension_field", "--wall-modulus-N-per-m", str(SOFT_WALL),
                 "--pressure-bar", "0.2:0.4:2", "--radius-mm", "60:90:2", "--length-m",
                 "1:1.5:2", "--tip-load-N", str(TIP_LOAD), "--chunk-size", "2", "--quiet",
                 "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted(["sweep.csv", "summary.json", "initial_stiffness.png",
                            "wrinkling_load.png", "collapse_load.png", "tip_deflection.png"])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["points"] == 8 and summary["failed_points"] == 0
    rows = np.genfromtxt(out / "sweep.csv", delimiter=",", names=True, dtype=None,
                         encoding="utf-8")
    assert rows.size == 8 and np.all(rows["converged"] == 1)
    grid = np.meshgrid([0.2e5, 0.4e5], [0.06, 0.09], [1.0, 1.5], indexing="ij")
    expected = sweep(jt.TensionFieldLaw(SOFT_WALL), *grid, TIP_LOAD, SETTINGS)
    np.testing.assert_allclose(rows["pressure_bar"], grid[0].reshape(-1) * 1e-5, rtol=1e-12)
    np.testing.assert_allclose(rows["radius_m"], grid[1].reshape(-1), rtol=1e-12)
    np.testing.assert_allclose(rows["pr3_Nm"], (grid[0] * grid[1] ** 3).reshape(-1), rtol=1e-9)
    for column, field, factor in (("wrinkling_load_N", "wrinkling_load", 1.0),
                                  ("collapse_load_N", "collapse_load", 1.0),
                                  ("tip_deflection_mm", "tip_deflection", 1e3)):
        np.testing.assert_allclose(rows[column],
                                   getattr(expected, field).reshape(-1) * factor, rtol=1e-9)


BAD = {
    "range order": (["--pressure-bar", "0.5:0.1:3"], "--pressure-bar", "START:STOP:N"),
    "range parts": (["--pressure-bar", "0.1:0.5"], "--pressure-bar", "START:STOP:N"),
    "zero radius": (["--radius-m", "0:0.1:3"], "--radius-m", "positive"),
    "no wall modulus": (["--no-modulus"], "--wall-modulus-N-per-m", "needs"),
    "negative load": (["--tip-load-N", "-3"], "--tip-load-N", ">= 0"),
    "missing params file": (["--params", "nothing.json"], "nothing.json", "not found"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_cli_bad_flags_exit_2_with_a_clear_message_and_write_nothing(tmp_path, capsys, case):
    changes, flag, words = BAD[case]
    args = {"--law": "tension_field", "--wall-modulus-N-per-m": "150e3",
            "--pressure-bar": "0.1:0.5:3", "--radius-m": "0.05:0.1:3", "--tip-load-N": "5"}
    if changes == ["--no-modulus"]:
        del args["--wall-modulus-N-per-m"]
    elif changes[0] == "--params":
        del args["--law"], args["--wall-modulus-N-per-m"]
        args["--params"] = str(tmp_path / changes[1])
    else:
        args[changes[0]] = changes[1]
    out = tmp_path / "out"
    argv = ["sweep", "--out", str(out)] + [x for kv in args.items() for x in kv]
    try:
        code = main(argv)
    except SystemExit as exit_:  # argparse rejects a malformed flag value
        code = exit_.code
    assert code == 2
    err = capsys.readouterr().err
    assert flag in err and words in err, err
    assert not out.exists()
