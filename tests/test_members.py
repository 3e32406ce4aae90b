"""``jaxtube.map_members`` and ``jaxtube.each_member``: independent solves as one program,
split over devices; every member equals its single solve, with its own convergence flags, on
one device and on two forced host devices (a 20-segment chain on the dense route, the
configuration in which a ``vmap`` per device deadlocked jaxlib's batched LU)."""

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

REPO = Path(__file__).resolve().parents[1]


def curve_function(segments, steps):
    """``(pressure [Pa], radius [m]) -> (control force [K], converged [K], Newton steps [K])``
    of a displacement-controlled cantilever curve on the dense route."""
    law = jt.SplineLaw.from_tension_field(150e3, 2e4, 0.075)
    structure, params = jt.cantilever(1.0, 0.075, 2e4, segments, law, jt.LinearLaw(500.0))
    control = jt.DisplacementControl(structure.node_id("tube:end"), [0.0, 0.0, -1.0],
                                     jnp.linspace(0.0, 0.3, steps + 1)[1:])

    def curve(pressure, radius):
        p = eqx.tree_at(lambda q: (q.pressure, q.node_radius), params,
                        (jnp.full_like(params.pressure, pressure),
                         jnp.full_like(params.node_radius, radius)))
        sol = jt.solve_path(structure, p, control, jt.NewtonKKT(linear_solver="dense"))
        return sol.control_force, sol.converged, sol.iterations

    return curve


def compare_with_single_solves(curve, pressures, radii):
    """``jt.map_members`` of ``curve`` over the members, checked member by member against
    the single curve (converged, the same Newton steps, forces to 1e-12)."""
    mapped = jt.map_members(curve)(jnp.asarray(pressures), jnp.asarray(radii))
    single = jax.jit(curve)
    for k, (p, r) in enumerate(zip(pressures, radii)):
        force, converged, steps = single(p, r)
        assert bool(jnp.all(converged)) and bool(jnp.all(mapped[1][k]))
        np.testing.assert_array_equal(np.asarray(mapped[2][k]), np.asarray(steps))
        np.testing.assert_allclose(np.asarray(mapped[0][k]), np.asarray(force), rtol=1e-12,
                                   atol=1e-12)
    return mapped


def test_members_on_one_device_equal_their_single_solves():
    mapped = compare_with_single_solves(curve_function(8, 4), [1.5e4, 2.5e4, 4e4],
                                        [0.06, 0.075, 0.09])
    assert mapped[0].shape == (3, 4)
    # Stiffer members carry more force at the same deflection (a check the test can fail).
    assert np.all(np.diff(np.asarray(mapped[0])[:, -1]) > 0)


def test_bad_member_axes_are_named():
    mapped = jt.map_members(lambda a, b: a + b)
    with pytest.raises(ValueError, match=r"leading \(member\) axes differ: \[2, 3\]"):
        mapped(np.zeros(2), np.zeros(3))
    with pytest.raises(ValueError, match="no members"):
        mapped(np.zeros(0), np.zeros(0))
    with pytest.raises(ValueError, match="leading member axis"):
        mapped(1.0, 2.0)
    np.testing.assert_array_equal(mapped(np.arange(3.0), np.ones(3)), [1.0, 2.0, 3.0])


def test_each_member_one_after_another_equals_vmap():
    def fn(x, y):
        return {"sum": jnp.sum(x) * y, "scaled": x * y}

    x, y = jnp.arange(12.0).reshape(4, 3), jnp.array([1.0, 2.0, -1.0, 0.5])
    one_by_one = jax.jit(lambda a, b: jt.each_member(fn, a, b, sequential=True))(x, y)
    batched = jt.each_member(fn, x, y, sequential=False)
    for key in ("sum", "scaled"):
        np.testing.assert_array_equal(one_by_one[key], batched[key])
    np.testing.assert_array_equal(one_by_one["sum"], [3.0, 24.0, -21.0, 15.0])


SPLIT = textwrap.dedent("""
    import os
    import sys
    # Held to 2 CPUs before JAX starts, so that XLA's CPU pool has no thread to spare beside
    # the 2 devices.
    os.sched_setaffinity(0, [int(c) for c in sys.argv[1].split(",")])
    import jax
    from tests.test_members import compare_with_single_solves, curve_function
    assert jax.device_count() == 2, jax.devices()
    mapped = compare_with_single_solves(curve_function(20, 5), [1.5e4, 2.5e4, 4e4],
                                        [0.06, 0.075, 0.09])  # 3 members: one padded
    assert mapped[0].shape == (3, 5)
    print("ok")
""")


def test_members_split_over_two_host_devices_equal_their_single_solves():
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    env.update(PYTHONPATH=str(REPO), JAX_PLATFORMS="cpu", JAXTUBE_CPU_DEVICES="2")
    cpus = ",".join(str(c) for c in sorted(os.sched_getaffinity(0))[:2])
    done = subprocess.run([sys.executable, "-c", SPLIT, cpus], env=env, cwd=REPO,
                          capture_output=True, text=True, timeout=400)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip().endswith("ok")
