"""The one-number search (bounded Brent, then both sides): finds an interior minimum to its
tolerance, flags a minimum at a bound, and stops and says so at an evaluation that did not
converge instead of walking on with a penalty."""

import pytest

import fitting


def test_interior_minimum_within_tolerance_and_checked_on_both_sides():
    calls = []

    def parabola(x):
        calls.append(x)
        return (x - 0.3) ** 2 + 2.0

    found = fitting.bounded_search(parabola, (-1.0, 2.0), xatol=1e-4, max_evaluations=50)
    assert found.converged and not found.at_bound
    assert found.x == pytest.approx(0.3, abs=1e-4)
    assert found.value == pytest.approx(2.0, abs=1e-7)
    assert found.step == 4e-4 and calls[-2:] == [found.x - 4e-4, found.x + 4e-4]
    assert min(found.value_minus_plus) >= found.value
    assert found.evaluations == len(calls)


def test_minimum_at_a_bound_is_not_converged():
    found = fitting.bounded_search(lambda x: x, (1.0, 2.0), xatol=1e-3, max_evaluations=50)
    assert found.at_bound and not found.converged
    assert found.x == pytest.approx(1.0, abs=2e-3)


@pytest.mark.parametrize("fails, during_brent", [
    (lambda x: x > 0.5, True),  # Brent's second point, 0.618
    (lambda x: 0.335 < x < 0.345, False),  # the side check at x + 4 xatol = 0.34
])
def test_an_evaluation_that_did_not_converge_stops_the_search(fails, during_brent):
    """``None`` (a solve that did not converge) is reported, never taken as a value: the
    search stops there, not converged, with the best point evaluated before it (after
    Brent: its minimum)."""
    calls = []

    def objective(x):
        calls.append(x)
        return None if fails(x) else (x - 0.3) ** 2

    found = fitting.bounded_search(objective, (0.0, 1.0), xatol=1e-2, max_evaluations=50)
    assert not found.converged and fails(calls[-1])
    assert f"x = {calls[-1]:.6g} did not converge" in found.message
    assert found.evaluations == len(calls)
    assert found.x == min(calls[:-1], key=lambda x: (x - 0.3) ** 2)
    assert (found.x == pytest.approx(0.3, abs=1e-2)) is not during_brent
    assert found.value_minus_plus == (None, None)
