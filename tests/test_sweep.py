"""``fitting.sweep`` and ``jaxtube sweep``: the planar route against single solves of the
generic 3-D solver, the generic route (models with effects) against the planar one at the
null, failures and not-applicable points in words, sharding over devices, the
``p r^3 / L`` scaling of the tension-field cantilever, and the command line.

Every sweep here uses the same settings and chunk shape (2 points), so the module compiles
the planar sweep once per law type (tension-field, spline, 2011 law), the generic route
once, one single-solve program per law type for the comparison, and the sharded program in
a subprocess. Compilation is most of this file's time.
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
from fitting import SelfWeight, SweepSettings, TubeModel, sweep
from fitting._bench.planar import deflection_residual, load_residual
from fitting._cli import main
from fitting._sweep.status import STATUS_NO_REGIME, STATUS_SOLVER_FAILED, STATUS_UNREACHABLE
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
TIP_LOAD = 6.0  # [N] (past the collapse load of specimen 0: a large-rotation deflection)
# A spline law through the soft tension-field law (3, 3, 3 pivots, exact p and r scaling).
SPLINE = jt.SplineLaw.from_tension_field(SOFT_WALL, 0.25e5, 0.075)
REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def soft():
    return sweep(jt.TensionFieldLaw(SOFT_WALL), PRESSURE, RADIUS, LENGTH, TIP_LOAD, SETTINGS)


@pytest.fixture(scope="module")
def stiff():
    return sweep(jt.TensionFieldLaw(STIFF_WALL), PRESSURE, RADIUS, LENGTH, TIP_LOAD, SETTINGS)


@pytest.fixture(scope="module")
def spline():
    return sweep(SPLINE, PRESSURE, RADIUS, LENGTH, TIP_LOAD, SETTINGS)


def test_every_point_converges_and_reports(soft, stiff, spline):
    for result in (soft, stiff, spline):
        assert result.route == "planar"
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
    """One compiled static solve (per law type) of a single, separately built cantilever
    under a dead tip load, from the unloaded shape (no load steps) with the generic 3-D
    solver: returns (converged, root moment [N m], tip deflection [m])."""
    structure, params = jt.cantilever(1.0, 0.075, 2e4, SETTINGS.segments,
                                      jt.TensionFieldLaw(SOFT_WALL))
    tip = structure.node_id("tube:end")

    @jax.jit
    def solve(law, pressure, radius, length, load):
        p = eqx.tree_at(lambda q: (q.node_position, q.node_radius, q.pressure, q.bending_laws),
                        with_tip_force(structure, params, jnp.stack([0.0, 0.0, -load])),
                        (params.node_position * length,
                         jnp.full_like(params.node_radius, radius),
                         jnp.full_like(params.pressure, pressure), (law,)))
        sol = jt.equilibrium(structure, p, solver=SETTINGS.solver)
        return (sol.converged, jnp.linalg.norm(sol.joint_moment[0, :2]),
                params.node_position[tip, 2] * length - sol.node_position[tip, 2])

    return solve


# Relative agreement of the planar route with the generic solver: measured at most 1e-10
# (root moments at the found loads) and 8e-10 (tip deflections) over these specimens, the
# soft and stiff walls and the spline, at 6 and 20 N; the generic solve itself stops at a
# gradient residual of 1e-10 relative.
AGREEMENT = 1e-8


@pytest.mark.parametrize("law_name, point", [("tension_field", 0), ("tension_field", 3),
                                              ("tension_field", 6), ("spline", 1),
                                              ("spline", 4)])
def test_sweep_agrees_with_single_solves(soft, spline, single_solve, law_name, point):
    """At the sweep's wrinkling and collapse loads, a separately built cantilever solved by
    the generic 3-D solver has the law's wrinkling / collapse moment at its root, and at
    the tip load the sweep's tip deflection (large rotations: 6 N is past the collapse load
    of specimen 0)."""
    result, law = {"tension_field": (soft, jt.TensionFieldLaw(SOFT_WALL)),
                   "spline": (spline, SPLINE)}[law_name]
    p, r, length = PRESSURE[point], RADIUS[point], LENGTH[point]
    if law_name == "tension_field":
        targets = (math.pi * p * r**3 / 2, 0.95 * math.pi * p * r**3)
    else:  # the onset and collapse pivots of the (3, 3, 3) spline
        pivot_moments = np.asarray(SPLINE.pivots(p, r)[1])
        targets = (pivot_moments[2], pivot_moments[5])
    for load, moment, target in ((result.wrinkling_load, result.wrinkling_moment, targets[0]),
                                 (result.collapse_load, result.collapse_moment, targets[1])):
        np.testing.assert_allclose(moment[point], target, rtol=1e-12)
        converged, root_moment, _ = single_solve(law, p, r, length, load[point])
        assert bool(converged)
        np.testing.assert_allclose(root_moment, target, rtol=AGREEMENT)
    converged, _, deflection = single_solve(law, p, r, length, TIP_LOAD)
    assert bool(converged)
    np.testing.assert_allclose(result.tip_deflection[point], deflection, rtol=AGREEMENT)


def test_tension_field_loads_scale_as_p_r3_over_length(stiff, soft):
    """Comer-Levy: F_w = (pi/2) p r^3 / L and F_c = 0.95 pi p r^3 / L within 1 % where the
    deflection at collapse is small; on the soft wall the lever arm's shortening shows."""
    scale = PRESSURE * RADIUS**3 / LENGTH
    np.testing.assert_allclose(stiff.wrinkling_load / scale, math.pi / 2, rtol=0.01)
    np.testing.assert_allclose(stiff.collapse_load / scale, 0.95 * math.pi, rtol=0.01)
    # Large-rotation equilibrium: the load always exceeds M / L (lever arm < L).
    assert np.all(stiff.collapse_load > 0.95 * math.pi * scale)
    assert np.all(soft.collapse_load / scale > stiff.collapse_load / scale)


def test_a_model_with_effects_takes_the_generic_route(soft):
    """An effect sends the sweep through the generic 3-D solver; at its null value that
    route agrees with the planar one (to the generic load iteration's moment tolerance).
    With a self-weight it runs and reports: the tube deflects further, and it wrinkles
    earlier where the generic load iteration converges (its 3 Newton steps on the load,
    made for a root moment that vanishes at zero load, do not always suffice with a
    weight), the reason given in words where not."""
    law, points = jt.TensionFieldLaw(SOFT_WALL), [0, 3]
    args = (PRESSURE[points], RADIUS[points], LENGTH[points], TIP_LOAD, SETTINGS)
    null = sweep(TubeModel(law, effects=(SelfWeight(0.0),)), *args)
    weighted = sweep(TubeModel(law, effects=(SelfWeight(0.02),)), *args)  # same program
    assert null.route == weighted.route == "generic"
    assert null.failed_count == 0, null.failure_reasons()
    # The generic iteration stops at |M_root / M - 1| <= 1e-6; the slope d ln M / d ln F
    # of these specimens is above 0.5, so the loads agree to 2e-6 (measured 1e-7).
    for name in ("wrinkling_load", "collapse_load"):
        np.testing.assert_allclose(getattr(null, name), getattr(soft, name)[points],
                                   rtol=2 * SETTINGS.moment_tolerance, err_msg=name)
    np.testing.assert_allclose(null.tip_deflection, soft.tip_deflection[points],
                               rtol=AGREEMENT)
    assert np.all(weighted.deflection_status == 0)
    assert np.all(weighted.tip_deflection > null.tip_deflection)
    ok = weighted.wrinkling_status == 0
    assert ok.any()
    assert np.all(weighted.wrinkling_load[ok] < null.wrinkling_load[ok])
    assert np.all(np.isnan(weighted.wrinkling_load[~ok]))
    for reason in weighted.failure_reasons()[~ok]:
        assert reason.startswith("wrinkling load: load iteration did not reach"), reason


def test_planar_jacobians_are_the_derivatives_of_the_residuals():
    """The closed-form Jacobians (law slopes by jvp, lever arms by hand) equal
    ``jax.jacfwd`` of the residuals, on a bent shape in the wrinkled regime."""
    law, p, r, length = jt.TensionFieldLaw(SOFT_WALL), 0.2e5, 0.08, 1.3

    @jax.jit
    def both(x):
        deflection = deflection_residual(law, p, r, length, 7.0, x)[1]
        load = load_residual(law, p, r, length, 2.0, x)[1]
        return deflection, load, jax.jacfwd(
            lambda y: (deflection_residual(law, p, r, length, 7.0, y)[0],
                       load_residual(law, p, r, length, 2.0, y)[0]))(x)

    x = jnp.linspace(0.12, 0.01, SETTINGS.segments).at[0].set(1.3)  # x[0]: F / F_0
    deflection, load, (expected_deflection, expected_load) = both(x)
    np.testing.assert_allclose(deflection, expected_deflection, rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(load, expected_load, rtol=1e-10, atol=1e-13)


def test_failures_and_unreachable_loads_are_reported_in_words():
    """Breukels' 2011 law: a valid specimen is fine; at r = 30 mm its initial stiffness is
    negative (outside the fit's validity), so no regime and no equilibrium, reported as a
    failure with a NaN value; a soft specimen whose root would need a first segment past the
    vertical to collapse gets "not applicable", not a failure."""
    law = jt.EmpiricalBendingLaw2011()
    result = sweep(law, [0.3e5, 0.1e5, 1.0082e4], [0.1, 0.03, 0.040634], [1.0, 1.0, 1.6437],
                   TIP_LOAD, SETTINGS)
    assert result.route == "planar"
    assert result.failure_reasons()[0] == "ok"
    assert np.asarray(law.initial_stiffness(0.1e5, 0.03)) < 0
    assert result.wrinkling_status[1] == result.collapse_status[1] == STATUS_NO_REGIME
    assert result.deflection_status[1] == STATUS_SOLVER_FAILED
    assert np.isnan(result.tip_deflection[1]) and result.failed[1]
    assert "tip deflection: equilibrium solve failed" in result.failure_reasons()[1]
    assert result.wrinkling_status[2] == 0 and np.isfinite(result.wrinkling_load[2])
    assert result.collapse_status[2] == STATUS_UNREACHABLE
    assert np.isnan(result.collapse_load[2]) and not result.failed[2]
    assert "past the vertical" in result.failure_reasons()[2]


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
    # Values to round-off: the partitioned program fuses differently (about 1 ulp measured).
    assert_same_sweep(np.load(out), soft, rtol=1e-13)


def assert_same_sweep(sharded, single, rtol):
    """Statuses and Newton step counts exactly, values to ``rtol``."""
    for name in COMPARED:
        if sharded[name].dtype.kind in "iub":
            np.testing.assert_array_equal(sharded[name], getattr(single, name), err_msg=name)
        else:
            np.testing.assert_allclose(sharded[name], getattr(single, name), rtol=rtol,
                                       atol=0, err_msg=name)


GENERIC_SHARDED = textwrap.dedent("""
    import os
    import sys
    # Held to the given CPUs before JAX starts: XLA sizes its CPU thread pool from them.
    os.sched_setaffinity(0, [int(c) for c in sys.argv[5].split(",")])
    import numpy as np
    import jax
    import jaxtube as jt
    from fitting import SelfWeight, SweepSettings, TubeModel, sweep
    assert len(jax.devices()) == 2, jax.devices()
    p, r, length, out = (np.load(sys.argv[1])[k] for k in ("p", "r", "length", "out"))
    model = TubeModel(jt.TensionFieldLaw(float(sys.argv[2])), effects=(SelfWeight(0.02),))
    result = sweep(model, p, r, length, float(sys.argv[3]),
                   SweepSettings(chunk_size=4, segments=20))
    assert result.devices == 2 and result.route == "generic"
    np.savez(str(out), **{k: getattr(result, k) for k in sys.argv[4].split(",")})
""")


def test_generic_route_sharded_over_two_host_devices_of_two_cores(tmp_path):
    """The generic route (a 20-segment chain: its KKT matrices are large enough for jaxlib's
    batched LU to split a batch over XLA's CPU thread pool) on 2 forced host devices, the
    process held to 2 CPUs so that the pool has no thread to spare: each device's points one
    after another, it finishes (a ``vmap`` per device hung here for good) and equals the
    single-device sweep."""
    points = [0, 1, 3, 5]
    inputs, out = tmp_path / "inputs.npz", tmp_path / "sharded.npz"
    np.savez(inputs, p=PRESSURE[points], r=RADIUS[points], length=LENGTH[points], out=str(out))
    flags = os.environ.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=2"
    env = dict(os.environ, XLA_FLAGS=flags.strip(), JAX_PLATFORMS="cpu", PYTHONPATH=str(REPO))
    cpus = ",".join(str(c) for c in sorted(os.sched_getaffinity(0))[:2])
    done = subprocess.run([sys.executable, "-c", GENERIC_SHARDED, str(inputs), str(SOFT_WALL),
                           str(TIP_LOAD), ",".join(COMPARED), cpus], env=env, cwd=REPO,
                          capture_output=True, text=True, timeout=400)
    assert done.returncode == 0, done.stderr[-3000:]
    model = TubeModel(jt.TensionFieldLaw(SOFT_WALL), effects=(SelfWeight(0.02),))
    single = sweep(model, PRESSURE[points], RADIUS[points], LENGTH[points], TIP_LOAD,
                   SweepSettings(chunk_size=4, segments=20), devices=jax.devices()[:1])
    assert_same_sweep(np.load(out), single, rtol=1e-12)


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
