"""Fit parameters to measured marker shapes by gradient, through the equilibrium and the
registration.

The objective is the peers' marker metric of a solved shape, with the markers registered
optimally for that shape:

    F(theta) = min_g RMS(surfaces(x*(theta)), markers, g)

where ``x*(theta)`` are the node positions of the equilibrium at parameters ``theta``
(``positions_of``, differentiated by the implicit function theorem inside jaxtube) and ``g``
the rigid registration (:func:`fitting.register`). **Gradient:** at the optimal
registration ``g*``, ``dRMS/dg = 0``, so ``dF/dtheta = dRMS/dx (x*, g*) dx*/dtheta`` with
``g*`` held fixed (envelope theorem); every evaluation of ``F`` re-registers, so the
gradient used is the gradient of ``F`` itself.

**Search** (:func:`fit_to_markers`): BFGS on ``theta`` with an Armijo backtracking line
search on ``F`` (re-registered at every trial point). The first step has length
``first_step`` in ``theta``'s units (for a log-parameter, a factor ``exp(first_step)``);
later steps use the BFGS curvature. It stops when the relative decrease of ``F`` over an
accepted step falls below ``rtol``, when the step is shorter than ``step_tolerance``, or after
``max_steps`` (reported as not converged). A solve that does not converge at a trial point
is a failed trial (the line search backs off); at the start it is an error.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from .markers import MarkerSet
from .registration import RegistrationResult, marker_rms, register
from .surfaces import TubeSurfaces


@dataclasses.dataclass(frozen=True)
class MarkerFit:
    """Outcome of :func:`fit_to_markers`.

    Attributes:
        parameters: ``[k]`` the fitted ``theta``.
        rms_m: ``F`` at ``parameters`` [m] (re-registered).
        gradient: ``[k]`` ``dF/dtheta`` there [m per unit of theta].
        registration: the optimal registration at ``parameters``.
        converged: a stopping test (not the step limit) ended the search.
        message: why it stopped.
        history: one dict per evaluation: ``theta``, ``rms_m``, ``gradient``, ``accepted``.
    """

    parameters: np.ndarray
    rms_m: float
    gradient: np.ndarray
    registration: RegistrationResult
    converged: bool
    message: str
    history: list


def fit_to_markers(
    positions_of: Callable,
    surfaces: TubeSurfaces,
    markers: MarkerSet,
    initial,
    *,
    first_step: float = 0.3,
    rtol: float = 1e-3,
    step_tolerance: float = 1e-3,
    max_steps: int = 12,
    spanwise_groups="auto",
    log: Callable[[str], None] | None = None,
) -> MarkerFit:
    """Minimise the registered marker RMS over ``theta`` (module docstring).

    Args:
        positions_of: ``theta [k] -> (node_positions [n, 3] [m], converged bool)``,
            traceable and differentiable in ``theta`` (e.g. a jaxtube solve).
        surfaces: the model's tube surfaces; only their node positions change
            (:meth:`TubeSurfaces.with_positions`).
        markers: the measured markers.
        initial: ``[k]`` starting ``theta``.
    """
    theta = np.atleast_1d(np.asarray(initial, dtype=float))

    @jax.jit
    def positions_and_jacobian(theta):
        # One compiled program: the solve and its tangents dx*/dtheta (forward mode through
        # the implicit function theorem, one tangent solve per parameter).
        def positions(theta):
            x, converged = positions_of(theta)
            return x, (x, converged)

        jacobian, (x, converged) = jax.jacfwd(positions, has_aux=True)(theta)
        return x, jacobian, converged

    @jax.jit
    def rms_and_position_gradient(positions, registration):
        return jax.value_and_grad(lambda x: marker_rms(surfaces.with_positions(x), markers,
                                                       registration))(positions)

    history: list = []

    def evaluate(theta):
        positions, jacobian, converged = jax.block_until_ready(
            positions_and_jacobian(jnp.asarray(theta)))
        if not bool(converged):
            history.append(dict(theta=theta.tolist(), rms_m=None, gradient=None,
                                accepted=False, note="solve did not converge"))
            return None
        found = register(surfaces.with_positions(positions), markers,
                         spanwise_groups=spanwise_groups)
        # Envelope theorem: the registration is held at its optimum for the derivative.
        value, position_gradient = rms_and_position_gradient(positions, found.registration)
        gradient = np.einsum("nd,ndk->k", np.asarray(position_gradient, dtype=float),
                             np.asarray(jacobian, dtype=float))
        history.append(dict(theta=theta.tolist(), rms_m=float(value),
                            gradient=gradient.tolist(), accepted=False))
        if log is not None:
            log(f"theta {np.round(theta, 5).tolist()}: RMS {1e3 * float(value):.2f} mm, "
                f"gradient {np.round(gradient * 1e3, 4).tolist()} mm per unit")
        return float(value), gradient, found

    current = evaluate(theta)
    if current is None:
        raise RuntimeError(f"fit_to_markers: the solve at the initial parameters {theta.tolist()}"
                           " did not converge")
    value, gradient, found = current
    history[-1]["accepted"] = True
    inverse_hessian = np.eye(theta.size) * first_step / max(np.linalg.norm(gradient), 1e-300)
    converged, message = False, f"stopped after {max_steps} steps"
    for _ in range(max_steps):
        direction = -inverse_hessian @ gradient
        slope = float(gradient @ direction)
        if slope >= 0:  # not a descent direction: restart from steepest descent
            inverse_hessian = np.eye(theta.size) * first_step / np.linalg.norm(gradient)
            direction = -inverse_hessian @ gradient
            slope = float(gradient @ direction)
        alpha, trial = 1.0, None
        for _ in range(6):
            candidate = theta + alpha * direction
            trial = evaluate(candidate)
            if trial is not None and trial[0] <= value + 1e-4 * alpha * slope:
                break
            trial = None
            alpha *= 0.5
        if trial is None:
            converged, message = True, "no decrease along the search direction (a minimum " \
                "to the line search's resolution)"
            break
        history[-1]["accepted"] = True
        step = candidate - theta
        change = trial[1] - gradient
        decrease = value - trial[0]
        theta, (value, gradient, found) = candidate, trial
        curvature = float(step @ change)
        if curvature > 1e-300:
            rho = 1.0 / curvature
            eye = np.eye(theta.size)
            inverse_hessian = (eye - rho * np.outer(step, change)) @ inverse_hessian @ (
                eye - rho * np.outer(change, step)) + rho * np.outer(step, step)
        if decrease <= rtol * value:
            converged, message = True, f"relative decrease {decrease / value:.2e} <= rtol"
            break
        if np.linalg.norm(step) <= step_tolerance:
            converged, message = True, f"step {np.linalg.norm(step):.2e} <= step_tolerance"
            break
    return MarkerFit(theta, value, gradient, found, converged, message, history)
