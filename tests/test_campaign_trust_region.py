"""The campaign calibration's search step (:mod:`fitting._campaign.calibrate`): the
registrations projected out, the Gauss-Newton step inside the trust region and the Levenberg
step on its boundary, against closed forms on small random systems."""

import numpy as np
import pytest

from fitting._campaign.calibrate import _predicted_fall, _projected_system, _trust_region_step

RNG = np.random.default_rng(3)


def system(values=3, cases=2, rows=60):
    """A least-squares system laid out as the calibration's: ``values`` columns, then six
    registration columns per case."""
    return RNG.normal(size=(rows, values + 6 * cases)), values


def test_projection_leaves_the_values_step_of_the_joint_solve():
    """Projecting the registrations out gives the values' part of the joint Gauss-Newton
    step (variable projection): exactly, for a residual any step explains."""
    jacobian, k = system()
    joint = RNG.normal(size=jacobian.shape[1])
    residual = -jacobian @ joint
    values_jacobian, projected = _projected_system(jacobian, residual, k)
    step = _trust_region_step(values_jacobian, projected, np.ones(k), radius=1e9)
    np.testing.assert_allclose(step, joint[:k], rtol=1e-10, atol=1e-12)
    with_noise = residual + RNG.normal(size=residual.size)
    values_jacobian, projected = _projected_system(jacobian, with_noise, k)
    full = -np.linalg.lstsq(jacobian, with_noise, rcond=None)[0]
    np.testing.assert_allclose(_trust_region_step(values_jacobian, projected, np.ones(k),
                                                  radius=1e9), full[:k], rtol=1e-10)


@pytest.mark.parametrize("radius", [1e-3, 0.1, 0.5])
def test_a_long_step_is_cut_to_the_radius_on_the_levenberg_path(radius):
    """Where the Gauss-Newton step is longer than the radius, the step has the radius's
    length in scaled coordinates, solves the damped normal equations for some damping, and
    its predicted fall is positive and below the Gauss-Newton step's."""
    jacobian, k = system()
    values_jacobian, residual = _projected_system(jacobian, 10 * RNG.normal(size=60), k)
    scale = np.array([1.0, 0.5, 2.0])
    newton = _trust_region_step(values_jacobian, residual, scale, radius=1e9)
    assert np.linalg.norm(newton / scale) > radius
    step = _trust_region_step(values_jacobian, residual, scale, radius)
    assert np.linalg.norm(step / scale) == pytest.approx(radius, rel=1e-6)
    scaled = values_jacobian * scale
    normal, gradient = scaled.T @ scaled, scaled.T @ residual
    unscaled = step / scale
    damping = -(normal @ unscaled + gradient) / unscaled  # the same in every coordinate
    assert np.ptp(damping) < 1e-6 * np.abs(damping).max() and damping[0] > 0
    assert 0 < _predicted_fall(values_jacobian, residual, step) < \
        _predicted_fall(values_jacobian, residual, newton)
