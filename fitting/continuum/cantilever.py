"""The planar continuum cantilever (Reissner kinematics): shooting, load and displacement
control, and the shape. Part of :mod:`fitting.continuum`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import NamedTuple

import numpy as np
from scipy import optimize
from scipy.integrate import solve_ivp

from .laws import BendingLaw, reinforced_law
from .scalar import (
    _EPS,
    _MAX_LOAD_FACTOR,
    _RUNAWAY_ANGLE,
    _RUNAWAY_CURVATURE,
    _RUNAWAY_RESIDUAL,
    GRAVITY,
)

# ---------------------------------------------------------------------------------------
# Cantilever model


class DeflectionOutOfReach(ValueError):
    """The requested tip deflection cannot be reached by any tip load of the model."""


class _Shot(NamedTuple):
    """One root-to-tip integration for a trial root curvature and tip load."""

    runaway: int  # 0, or the sign of theta where a section turned past vertical
    x_tip: float  # tip position relative to the root [m]
    y_tip: float  # (y downward)
    tip_angle: float  # [rad]
    tip_moment: float  # bending moment left at the free end [N m]; zero at equilibrium
    remaining: float  # arc length not reached on a run-away [m]
    solution: object  # solve_ivp result (dense output when requested)


@dataclasses.dataclass(frozen=True, eq=False)
class CantileverShape:
    """Equilibrium centreline, root to tip (arrays of shape ``[n]``).

    Attributes:
        arclength: s [m] from the root.
        x: horizontal position [m] from the root.
        y: vertical position [m] from the root, positive downward.
        rotation: section rotation theta [rad], positive downward.
        moment: bending moment [N m] (positive bends the tube downward).
        load: the tip load P [N] (downward positive).
        root_curvature: curvature at the root [1/m].
    """

    arclength: np.ndarray
    x: np.ndarray
    y: np.ndarray
    rotation: np.ndarray
    moment: np.ndarray
    load: float
    root_curvature: float


@dataclasses.dataclass(frozen=True)
class CantileverModel:
    """Planar continuum cantilever with optional shear, clamp compliance, reinforcement and
    self-weight (equations in the module docstring).

    Attributes:
        length: L [m].
        law: bending law of the tube (:class:`BendingLaw`).
        shear_stiffness: Fichter shear stiffness ``S = p pi r^2 + k G t 2 pi r`` [N]
            (see :func:`fichter_shear_stiffness`); None = no shear deformation.
        clamp_stiffness: rotational spring at the root ``k_clamp`` [N m/rad]; root rotation
            ``M_root / k_clamp``; None = rigid clamp.
        reinforcement_stiffness: ``EI_r`` [N m^2] in parallel with the law (0 = none).
        mass_per_length: w [kg/m] for self-weight (0 = weightless).
        tip_mass: a point mass [kg] hanging at the tip (its weight ``tip_mass g`` is a dead
            tip load present before loading, not part of the measured load).
        gravity: g [m/s^2].
        rtol: relative tolerance of the ODE solver; the absolute tolerances are ``rtol``
            times L (positions), 1 rad (angle) and a moment scale.
    """

    length: float
    law: BendingLaw
    shear_stiffness: float | None = None
    clamp_stiffness: float | None = None
    reinforcement_stiffness: float = 0.0
    mass_per_length: float = 0.0
    tip_mass: float = 0.0
    gravity: float = GRAVITY
    rtol: float = 1e-10

    def __post_init__(self):
        if not self.length > 0.0:
            raise ValueError(f"length must be > 0 [m], got {self.length}")
        if self.shear_stiffness is not None and not self.shear_stiffness > 0.0:
            raise ValueError(f"shear_stiffness must be > 0 [N] or None, got {self.shear_stiffness}")
        if self.clamp_stiffness is not None and not self.clamp_stiffness > 0.0:
            raise ValueError(
                f"clamp_stiffness must be > 0 [N m/rad] or None, got {self.clamp_stiffness}"
            )
        if min(self.reinforcement_stiffness, self.mass_per_length, self.tip_mass) < 0.0:
            raise ValueError("reinforcement_stiffness, mass_per_length and tip_mass must be "
                             ">= 0")

    # -- internals ----------------------------------------------------------------------

    @functools.cached_property
    def _bending_law(self) -> BendingLaw:
        return reinforced_law(self.law, self.reinforcement_stiffness)

    @property
    def _weight_per_length(self) -> float:
        return self.mass_per_length * self.gravity  # N/m

    @functools.cached_property
    def _curvature_scale(self) -> float:
        return 0.01 / self.length  # 1/m: a small-deflection curvature

    @functools.cached_property
    def _moment_scale(self) -> float:
        """Moment [N m] at the curvature scale: normalises the tip-moment residual."""
        return abs(float(self._bending_law.moment(self._curvature_scale)))

    @functools.cached_property
    def _force_scale(self) -> float:
        """Tip load [N] that bends the tube to about the curvature scale."""
        return self._moment_scale / self.length

    def _integrate(self, root_curvature: float, load: float, dense: bool = False) -> _Shot:
        """Integrate root (s = 0) to tip (s = L) from a trial root curvature [1/m]."""
        length = self.length
        weight = self._weight_per_length
        tip_load = load + self.tip_mass * self.gravity  # measured load + the hanging mass
        shear = self.shear_stiffness
        law = self._bending_law
        curvature = law.curvature
        limit = law.moment_limit

        def rhs(s, state):
            theta, moment = state[2], state[3]
            resultant = tip_load + weight * (length - s)  # V: downward resultant beyond s
            # Past the moment limit (or at absurd curvature) the trial is running away
            # anyway; a capped curvature lets it turn past vertical in a few steps.
            kappa = float(curvature(float(moment))) if abs(moment) < limit else math.inf
            if not abs(kappa) <= runaway_curvature:
                kappa = math.copysign(runaway_curvature, moment)
            cos_t, sin_t = math.cos(theta), math.sin(theta)
            if shear is None:
                dx, dy = cos_t, sin_t
            else:
                gamma = resultant * cos_t / shear  # V_perp / S
                dx, dy = cos_t - gamma * sin_t, sin_t + gamma * cos_t
            return np.array([dx, dy, kappa, -resultant * dx])

        def turned_past_vertical(s, state):
            # Equilibria under downward dead loads keep |theta| < pi/2; a trial whose
            # section turns past that has far too much (or too little) root curvature.
            return abs(state[2]) - _RUNAWAY_ANGLE

        turned_past_vertical.terminal = True
        runaway_curvature = _RUNAWAY_CURVATURE / length
        if not abs(root_curvature) <= runaway_curvature:
            sign = 1 if root_curvature > 0.0 else -1
            return _Shot(sign, 0.0, 0.0, sign * _RUNAWAY_ANGLE, 0.0, length, None)
        root_moment = float(law.moment(float(root_curvature)))
        root_rotation = 0.0 if self.clamp_stiffness is None else root_moment / self.clamp_stiffness
        moment_scale = max(abs(root_moment), self._moment_scale)
        solution = solve_ivp(
            rhs,
            (0.0, length),
            np.array([0.0, 0.0, root_rotation, root_moment]),
            method="DOP853",
            rtol=self.rtol,
            atol=self.rtol * np.array([length, length, 1.0, moment_scale]),
            events=turned_past_vertical,
            dense_output=dense,
        )
        x, y, theta, moment = solution.y[:, -1]
        runaway = 0 if solution.status == 0 else (1 if theta > 0.0 else -1)
        remaining = length - solution.t[-1] if runaway else 0.0
        return _Shot(runaway, x, y, theta, moment, remaining, solution)

    def _tip_residual(self, shot: _Shot) -> float:
        """``asinh(M(L) / moment scale)``: increasing in the root curvature, zero at
        equilibrium; a run-away trial is placed beyond every regular value on its side."""
        if shot.runaway:
            return shot.runaway * (_RUNAWAY_RESIDUAL + shot.remaining / self.length)
        return math.asinh(shot.tip_moment / self._moment_scale)

    def _shoot(self, load: float) -> tuple[float, _Shot]:
        """Root curvature [1/m] and shot that satisfy ``M(L) = 0`` under tip load ``load``."""

        def residual(root_curvature):
            return self._tip_residual(self._integrate(root_curvature, load))

        at_zero = residual(0.0)
        if at_zero == 0.0:
            return 0.0, self._integrate(0.0, load)
        sign = 1.0 if at_zero < 0.0 else -1.0  # the way the root curvature must go
        # First upper bracket: the curvature of the small-deflection root moment, which
        # large deflections only reduce (shorter lever arms).
        law = self._bending_law
        root_moment = (abs(load + self.tip_mass * self.gravity) * self.length
                       + 0.5 * self._weight_per_length * self.length**2)
        root_moment = min(root_moment, (1.0 - 1e-6) * law.moment_limit)
        first = abs(float(law.curvature(root_moment)))
        lo, hi = 0.0, sign * (first if first > 0.0 else self._curvature_scale)
        while sign * residual(hi) < 0.0:
            lo, hi = hi, 2.0 * hi
            if abs(hi) > 1e300:
                raise RuntimeError(f"shooting failed for tip load {load} N ({self.law.name})")
        root_curvature = optimize.brentq(residual, lo, hi, xtol=1e-300, rtol=4 * _EPS)
        shot = self._integrate(root_curvature, load)
        if shot.runaway:
            raise RuntimeError(f"shooting failed for tip load {load} N ({self.law.name})")
        return root_curvature, shot

    @functools.cached_property
    def _unloaded(self) -> tuple[float, float]:
        """Root curvature [1/m] and tip sag [m] of the unloaded shape (self-weight and tip
        mass only)."""
        if self._weight_per_length == 0.0 and self.tip_mass == 0.0:
            return 0.0, 0.0
        root_curvature, shot = self._shoot(0.0)
        return root_curvature, shot.y_tip

    # -- force control ------------------------------------------------------------------

    def tip_position(self, load: float) -> tuple[float, float]:
        """Tip position ``(x, y)`` [m] relative to the root, y positive downward, under a
        dead tip load ``load`` [N] (downward positive)."""
        _, shot = self._shoot(float(load))
        return float(shot.x_tip), float(shot.y_tip)

    def tip_deflection(self, load: float) -> float:
        """Vertical tip displacement [m], positive downward, from the unloaded shape."""
        return self.tip_position(load)[1] - self._unloaded[1]

    def shape(self, load: float, num_points: int = 101) -> CantileverShape:
        """Equilibrium centreline under tip load ``load`` [N], ``num_points`` points."""
        root_curvature, _ = self._shoot(float(load))
        full = self._integrate(root_curvature, float(load), dense=True)
        arclength = np.linspace(0.0, self.length, num_points)
        x, y, theta, moment = full.solution.sol(arclength)
        return CantileverShape(arclength, x, y, theta, moment, float(load), root_curvature)

    # -- displacement control -----------------------------------------------------------
    #
    # Unknowns are scaled: ``u = asinh(kappa_0 / kappa_scale)`` (log-like on a collapse
    # plateau, where the root curvature grows fast) and ``p = load / force_scale``.

    def _to_physical(self, unknowns) -> tuple[float, float]:
        return (
            self._curvature_scale * math.sinh(unknowns[0]),
            float(unknowns[1]) * self._force_scale,
        )

    def _displacement_residual(self, unknowns, target: float) -> np.ndarray:
        """``[asinh(M(L) / M_scale), (deflection - target) / L]``."""
        root_curvature, load = self._to_physical(unknowns)
        shot = self._integrate(root_curvature, load)
        if shot.runaway:
            return np.array([self._tip_residual(shot), float(shot.runaway)])
        deflection = shot.y_tip - self._unloaded[1]
        return np.array([self._tip_residual(shot), (deflection - target) / self.length])

    def _newton_force(self, target: float, guess, jacobian=None):
        """Scaled unknowns for a ``target`` deflection [m], by Broyden-updated Newton.

        Starts from ``guess`` (scaled unknowns) and ``jacobian`` (e.g. from the previous
        point of a curve; else by forward differences). A step that does not reduce the
        max-norm residual first refreshes the Jacobian, then is halved. The load is kept on
        the side of the target. Returns ``(unknowns, jacobian)``, or None when it does not
        converge (callers then take smaller continuation steps, or bracket).
        """
        direction = 1.0 if target > 0.0 else -1.0

        def admissible(u):
            return np.array([u[0], direction * max(direction * u[1], 0.0)])

        def finite_difference_jacobian(u, residual):
            columns = []
            for j in range(2):
                shifted = u.copy()
                shifted[j] += 1e-7 * max(abs(u[j]), 1e-2)
                columns.append(
                    (self._displacement_residual(shifted, target) - residual) / (shifted[j] - u[j])
                )
            return np.column_stack(columns)

        unknowns = admissible(np.asarray(guess, dtype=float))
        residual = self._displacement_residual(unknowns, target)
        if jacobian is None:
            jacobian, fresh = finite_difference_jacobian(unknowns, residual), True
        else:
            fresh = False
        for _ in range(12):
            norm = float(np.max(np.abs(residual)))
            if norm < 1e-12:
                break
            try:
                step = np.linalg.solve(jacobian, -residual)
            except np.linalg.LinAlgError:
                step = None
            damping, trial = 1.0, None
            while step is not None and damping >= 1.0 / 16.0:
                candidate = admissible(unknowns + damping * step)
                candidate_residual = self._displacement_residual(candidate, target)
                if float(np.max(np.abs(candidate_residual))) < norm:
                    trial, trial_residual = candidate, candidate_residual
                    break
                if not fresh:
                    break  # an old Jacobian: refresh it before damping
                damping *= 0.5
            if trial is None:
                if fresh:
                    break  # no descent with an exact Jacobian: noise floor, or lost
                jacobian, fresh = finite_difference_jacobian(unknowns, residual), True
                continue
            change = trial - unknowns
            # Broyden's ("good") rank-one update.
            jacobian = jacobian + np.outer(
                trial_residual - residual - jacobian @ change, change
            ) / float(change @ change)
            fresh = False
            unknowns, residual = trial, trial_residual
            if np.all(np.abs(change) <= 1e-13 * (1.0 + np.abs(unknowns))):
                break
        if not float(np.max(np.abs(residual))) < 1e-9:
            return None
        return unknowns, jacobian

    def _continue(self, target: float, history: list, jacobian=None):
        """Follow the equilibrium path from ``history[-1]`` to the deflection ``target``.

        ``history`` holds ``(deflection [m], scaled unknowns)`` of solved points on one side
        of zero, starting with the unloaded state. Predictor: linear extrapolation of the
        physical root curvature and the load through the last two points (from the unloaded
        state alone, the small-load response); extrapolating ``asinh`` linearly would
        overshoot wildly. Corrector: :meth:`_newton_force`. A failed corrector halves the
        step, a success doubles it. Solved points are appended to ``history``. Returns
        ``(unknowns, jacobian)`` at ``target``, or None.
        """
        kappa_scale = self._curvature_scale
        step = target - history[-1][0]
        while abs(step) > 1e-6 * abs(target):
            last, unknowns = history[-1]
            next_deflection = target if abs(target - last) <= abs(step) else last + step
            curvature = kappa_scale * math.sinh(unknowns[0])
            if len(history) >= 2:
                previous_deflection, previous = history[-2]
                run = last - previous_deflection
                curvature_rate = (curvature - kappa_scale * math.sinh(previous[0])) / run
                load_rate = (unknowns[1] - previous[1]) / run
            else:
                compliance, curvature_per_load = self._linear_response
                curvature_rate = curvature_per_load / compliance
                load_rate = 1.0 / (compliance * self._force_scale)
            increment = next_deflection - last
            guess = np.array(
                [
                    math.asinh((curvature + increment * curvature_rate) / kappa_scale),
                    unknowns[1] + increment * load_rate,
                ]
            )
            solved = self._newton_force(next_deflection, guess, jacobian)
            if solved is None:
                step *= 0.5
                jacobian = None
                continue
            unknowns, jacobian = solved
            history.append((next_deflection, unknowns))
            if next_deflection == target:
                return unknowns, jacobian
            step *= 2.0
        return None

    def _unloaded_history(self) -> list:
        """``[(0, scaled unknowns of the unloaded state)]``: where continuation starts."""
        return [(0.0, np.array([math.asinh(self._unloaded[0] / self._curvature_scale), 0.0]))]

    def _bracketed_force(self, target: float) -> float:
        """Robust fallback: Brent on the load, each evaluation a full shooting solve.

        The load doubles from the force scale until the deflection passes the target; it
        gives up at ``_MAX_LOAD_FACTOR`` force scales.
        """

        def excess(load):
            return self.tip_deflection(load) - target

        direction = 1.0 if target >= 0.0 else -1.0
        lo, hi = 0.0, direction * self._force_scale
        while abs(hi) <= _MAX_LOAD_FACTOR * self._force_scale:
            try:
                value = excess(hi)
            except RuntimeError:
                break
            if direction * value >= 0.0:
                return optimize.brentq(excess, lo, hi, xtol=1e-14 * abs(hi), rtol=4 * _EPS)
            lo, hi = hi, 2.0 * hi
        raise DeflectionOutOfReach(
            f"tip deflection {target:.6g} m not reached by the model ({self.law.name}, "
            f"L={self.length} m): the largest load solved, {lo:.4g} N, gives "
            f"{self.tip_deflection(lo):.6g} m. Either the deflection is beyond the model's "
            "reach, or the tube would hang so nearly vertical that shooting is "
            "ill-conditioned (load parameter P L^2 / EI above about 1000)."
        )

    @functools.cached_property
    def _linear_response(self) -> tuple[float, float]:
        """Small-load tip compliance [m/N] and root-curvature sensitivity [1/(m N)]."""
        load = 1e-3 * self._force_scale
        root_curvature, shot = self._shoot(load)
        return (
            (shot.y_tip - self._unloaded[1]) / load,
            (root_curvature - self._unloaded[0]) / load,
        )

    def _check_reach(self, target: float) -> None:
        if self.shear_stiffness is None:
            # Inextensible: the tip stays within L of the root.
            sag = self._unloaded[1]
            reach = self.length - sag if target > 0.0 else self.length + sag
            if abs(target) >= reach:
                raise DeflectionOutOfReach(
                    f"tip deflection {target} m is beyond the reach ({reach:.6g} m) of an "
                    f"inextensible tube of length {self.length} m"
                )

    def _solve_deflection(self, target: float, history: list, jacobian=None):
        """``(load [N], jacobian)`` at deflection ``target`` [m]: continuation along
        ``history`` (see :meth:`_continue`), else Brent on the load."""
        if target == 0.0:
            return 0.0, jacobian
        self._check_reach(target)
        solved = self._continue(target, history, jacobian)
        if solved is not None:
            return self._to_physical(solved[0])[1], solved[1]
        load = self._bracketed_force(target)
        root_curvature = self._shoot(load)[0]
        unknowns = np.array(
            [math.asinh(root_curvature / self._curvature_scale), load / self._force_scale]
        )
        history.append((target, unknowns))
        return load, None

    def tip_force(self, deflection: float) -> float:
        """Dead tip load [N] that gives the tip deflection ``deflection`` [m] (displacement
        control; positive downward, measured from the unloaded shape).

        Works wherever the force-deflection curve is monotone, including the collapse
        plateau of a softening law (continuation from the unloaded state with adaptive
        steps, then a bracketing fallback).

        Raises:
            DeflectionOutOfReach: no tip load (up to ``_MAX_LOAD_FACTOR`` force scales)
                reaches that deflection.
        """
        return self._solve_deflection(float(deflection), self._unloaded_history())[0]

    def curve(self, deflections) -> np.ndarray:
        """Tip loads [N] at tip deflections [m] (array of any shape and order).

        Solved in order of increasing ``|deflection|`` on each side of zero by
        continuation (secant predictor, Broyden corrector reusing the Jacobian), so a
        curve costs a few ODE solves per point.
        """
        deflections = np.asarray(deflections, dtype=float)
        flat = deflections.reshape(-1)
        forces = np.zeros(flat.shape)
        for positive in (True, False):
            history, jacobian = self._unloaded_history(), None
            for i in np.argsort(np.abs(flat)):
                target = float(flat[i])
                if target != 0.0 and (target > 0.0) == positive:
                    forces[i], jacobian = self._solve_deflection(target, history, jacobian)
        return forces.reshape(deflections.shape)


