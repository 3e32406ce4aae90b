"""The nonmonotone Armijo tests of the Newton-KKT solver (``NewtonKKT.nonmonotone_window``):
the recent merits it compares with, and the Maratos example of Nocedal & Wright (2006,
Example 15.4) against its closed-form solution."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxtube as jt
from jaxtube._solver import newton_kkt
from jaxtube._solver.kkt_step import RecentMerits


def test_recent_merits_keep_the_last_window_and_compare_at_the_current_penalty():
    merits = RecentMerits.empty(3, jnp.float64)
    assert float(merits.reference(2.0, 10.0)) == 2.0  # nothing recorded: the iterate's own
    for energy, violation in [(5.0, 0.0), (1.0, 1.0), (0.0, 0.5), (-1.0, 0.0)]:
        merits = merits.record(energy, violation, True)
    np.testing.assert_array_equal(merits.energy, [1.0, 0.0, -1.0])  # the oldest dropped
    assert float(merits.reference(-3.0, 0.5)) == 1.5  # 1 + 0.5 * 1
    assert float(merits.reference(-3.0, 4.0)) == 5.0  # the penalty weighs the violation
    kept = merits.record(100.0, 100.0, False)
    np.testing.assert_array_equal(kept.energy, merits.energy)
    with pytest.raises(ValueError, match="at least 1"):
        RecentMerits.empty(0, jnp.float64)


def _maratos(z, args):
    """min 2 (x^2 + y^2 - 1) - x subject to x^2 + y^2 = 1: the solution (1, 0) with the
    multiplier -3/2 (stationarity 4x - 1 + 2 lambda x = 0 at x = 1)."""
    x = z["x"]
    circle = x[0] ** 2 + x[1] ** 2 - 1.0
    return jnp.stack([2.0 * circle - x[0]]), jnp.stack([circle])


def test_the_maratos_example_is_solved_with_fewer_corrections_by_the_nonmonotone_test(
        monkeypatch):
    """On the circle the full Newton step raises the l1 merit through the constraint's
    curvature although it heads for the solution (the Maratos effect). The monotone test
    (a window of 1) refuses such steps and corrects them; a window of three iterates takes
    them. Both reach the closed-form solution."""
    corrections = []
    plain = newton_kkt.second_order_correction

    def counted(*args, **kwargs):
        out = plain(*args, **kwargs)
        jax.debug.callback(lambda _: corrections.append(1), out)
        return out

    monkeypatch.setattr(newton_kkt, "second_order_correction", counted)
    used = {}
    for window in (1, 3):
        corrections.clear()
        result = jt.solve_equilibrium(_maratos, {"x": jnp.asarray([0.3, 1.2])}, None,
                                      jt.NewtonKKT(nonmonotone_window=window))
        assert bool(result.converged)
        np.testing.assert_allclose(result.state["x"], [1.0, 0.0], atol=1e-10)
        np.testing.assert_allclose(result.multipliers, [-1.5], atol=1e-10)
        used[window] = len(corrections)
    assert used[3] < used[1], used
