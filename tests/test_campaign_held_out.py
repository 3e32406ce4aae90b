"""The shape diagnosis' linearised held-out score (``linearised_held_out`` of
:mod:`fitting._campaign.diagnose`) on a model linear in its values, where it has a closed
form: each case's score is the refit of the values without that case, with the case's own
registration fitted to it."""

import math

import numpy as np
import pytest

import fitting
from fitting._campaign.diagnose import linearised_held_out

RNG = np.random.default_rng(11)
CASES = {"a": 30, "b": 24, "c": 40}
#: A factor (searched by its logarithm) and two offsets, with bounds no step here reaches.
NAMES = ("bending_scale", "pressure_offset_bar", "suspension_offsets_mm.1.x")
BOUNDS = {"bending_scale": (1e-3, 1e3), "pressure_offset_bar": (-1e3, 1e3),
          "suspension_offsets_mm.1.x": (-1e3, 1e3)}


def linear_fit():
    """A :class:`fitting.CampaignCalibration` at the least-squares optimum of the residual
    ``offset + J @ (theta, registrations)`` (``theta`` the values' search coordinates: the
    factor's logarithm), with its system, and ``(jacobian [M, 3 + 6 C], offset [M])``."""
    count = sum(CASES.values())
    jacobian = np.zeros((count, len(NAMES) + 6 * len(CASES)))
    rows, row = {}, 0
    for c, (case, m) in enumerate(CASES.items()):
        rows[case] = (row, row + m)
        jacobian[row:row + m, :len(NAMES)] = RNG.normal(size=(m, len(NAMES)))
        jacobian[row:row + m, len(NAMES) + 6 * c:len(NAMES) + 6 * c + 6] = \
            RNG.normal(size=(m, 6))
        row += m
    offset = 1e-3 * RNG.normal(size=count)
    solution = -np.linalg.lstsq(jacobian, offset, rcond=None)[0]
    residual = offset + jacobian @ solution
    values = np.asarray([math.exp(solution[0]), *solution[1:3]])
    model = fitting.with_values(fitting.KiteModel(), NAMES, values)
    k = len(NAMES)
    fit = fitting.CampaignCalibration(
        model, NAMES, values, np.full(k, np.nan), np.eye(k), (), {}, {}, True, "", 1,
        float(residual @ residual), count, count - jacobian.shape[1],
        (jacobian, residual, rows))
    return fit, jacobian, offset


def test_linearised_held_out_is_the_refit_without_the_case():
    """Each case's linearised held-out RMS is that case's residual RMS with the values
    fitted to the other cases (their registrations free) and the case's own registration
    fitted to it."""
    fit, jacobian, offset = linear_fit()
    held = linearised_held_out(fit, BOUNDS)
    _, _, rows = fit.least_squares
    for c, (case, (first, last)) in enumerate(rows.items()):
        others = np.ones(len(offset), bool)
        others[first:last] = False
        values = -np.linalg.lstsq(jacobian[others], offset[others], rcond=None)[0][:3]
        own = offset[first:last] + jacobian[first:last, :3] @ values
        registration = jacobian[first:last, 3 + 6 * c:9 + 6 * c]
        own -= registration @ np.linalg.lstsq(registration, own, rcond=None)[0]
        assert held[case] == pytest.approx(1e3 * np.sqrt(np.mean(own ** 2)), rel=1e-9)
        # Leaving the case out costs something: the held-out RMS exceeds the case's own.
        assert held[case] > 1e3 * np.sqrt(np.mean(fit.least_squares[1][first:last] ** 2))
