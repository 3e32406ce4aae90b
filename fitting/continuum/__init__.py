"""Independent continuum reference: a planar large-deflection cantilever in numpy/scipy.

This module does **not** import jaxtube. It solves the same physical problem as the
rigid-segment engine by a different route (a continuum beam integrated by a high-order
ODE solver), so that agreement between the two is evidence and not an echo. It also makes
synthetic "measured" force-deflection curves for testing the fitting and diagnosis code.

Moment-curvature laws (all SI: curvature in 1/m, moment in N m)
----------------------------------------------------------------
A law is a monotone, point-symmetric pair ``moment(curvature)`` / ``curvature(moment)``
(:class:`BendingLaw`). Provided:

- :func:`linear_law`: ``M = EI kappa``.
- :func:`tension_field_law` (no-compression membrane tube, docs/physics.md, section 2.3, after
  Comer & Levy 1963): ``EI = pi Et r^3`` up to ``kappa_w = p / (2 Et)``; beyond, with ``a``
  the half-angle of the taut arc (pi down to 0)::

      kappa(a) = pi p / (2 Et (sin a - a cos a))
      M(a)     = (pi p r^3 / 2) (a - sin a cos a) / (sin a - a cos a)

  so ``M_w = pi p r^3 / 2`` at onset and ``M -> M_c = pi p r^3`` as ``kappa -> inf``. The
  plain functions :func:`tension_field_moment` and :func:`tension_field_curvature` invert the
  parametric form for ``a`` (safeguarded Newton, small-``a`` Taylor series to avoid the
  cancellation in ``sin a - a cos a``), to about 1e-13 relative.
- :func:`law_from_moment`: any monotone ``M(kappa)``; its inverse is found numerically.
- :func:`reinforced_law`: ``M(kappa) + EI_r kappa`` (pressure-independent reinforcement).

Cantilever model (:class:`CantileverModel`)
-------------------------------------------
A horizontal beam of length ``L``, clamped at the root ``s = 0``, dead vertical tip load
``P`` (downward positive), optional self-weight ``w g`` per unit length (dead load along the
deformed centreline). Frame: ``x`` along the undeformed axis from the root, ``y``
**downward**; ``theta(s)`` is the rotation of the cross-section, positive when the section
turns downward (clockwise in a y-up picture). Inextensible Reissner kinematics with the
Fichter shear strain ``gamma``::

    dx/ds     = cos(theta) - gamma sin(theta)
    dy/ds     = sin(theta) + gamma cos(theta)
    dtheta/ds = kappa(M(s))          (M = M_law(kappa) + EI_r kappa)
    dM/ds     = -V(s) dx/ds,         V(s) = P + w g (L - s)

``V(s)`` is the downward resultant of all loads beyond ``s`` (inextensible, so the weight
beyond ``s`` is ``w g (L - s)`` whatever the shape) and ``M(s)`` their moment about the
centreline point at ``s`` (positive when it bends the tube downward). Shear (Fichter 1966;
Le van & Wielgosz 2005, docs/physics.md, section 2.4) uses the resultant's component *perpendicular
to the deformed section*, ``V_perp = V cos(theta)`` (the component ``V sin(theta)`` along
the section normal is axial force and does not shear)::

    gamma = V cos(theta) / S,        S = p pi r^2 + k G t 2 pi r    [N]

Boundary conditions: at the root ``x = y = 0`` and the section rotation is the clamp
rotation ``theta(0) = M(0) / k_clamp`` (zero for a rigid clamp); at the free end
``M(L) = 0``.

Solution method. Because the tube is inextensible, ``V(s)`` is known in closed form for
any shape, so the equations can be integrated from the root to the tip with
:func:`scipy.integrate.solve_ivp` (DOP853, rtol 1e-10) from a trial *root curvature*
``kappa_0`` (``M(0) = M(kappa_0)``); the moment of the weight on the deformed part beyond
``s`` is carried by ``dM/ds = -V dx/ds`` (equivalent to a tip-to-root integration with
``(x, y, theta, M, V)``). Shooting on ``M(L) = 0``, which increases monotonically with
``kappa_0``, is done by Brent's method on a doubling bracket. Shooting on the root
curvature rather than the tip angle keeps every trial finite and well-conditioned on a
collapse plateau: a tip-angle trial runs into ``M >= M_c`` (infinite curvature) whenever
the load is too large for it, while a root-curvature trial only ever sees ``|M| <= M(0)``
until it turns past vertical, which flags it as run-away.

Displacement control (:meth:`CantileverModel.tip_force`, :meth:`CantileverModel.curve`)
solves for ``(kappa_0, P)`` together: continuation in the deflection from the unloaded
state (secant predictor, Broyden-updated Newton corrector with step halving; unknowns
``asinh(kappa_0 / kappa_s)`` and ``P / P_s``), adaptive step, and Brent on the load as a
last resort. This follows the curve wherever it is monotone, including the collapse
plateau of a softening law.

The tip deflection is measured from the *unloaded* shape (``P = 0``, which sags under
self-weight), as a bench test zeroes its gauge.

Closed form (:func:`elastica_tip`): the elliptic-integral elastica of a cantilever with a
dead tip load (Mattiasson 1981; docs/physics.md, section 4.1).

Sources: docs/physics.md, sections 2 and 4; Comer & Levy, AIAA J. 1 (1963) (wrinkling and
collapse moments); Fichter, NASA technical note (1966), and Le van & Wielgosz,
Thin-Walled Struct. 43 (2005) (pressure term in the shear stiffness); Mattiasson, Int. J.
Numer. Meth. Eng. 17 (1981) (elliptic-integral elastica); Reissner, ZAMP 23 (1972) (planar
shear-deformable finite-strain beam kinematics).
"""


from .cantilever import CantileverModel, CantileverShape, DeflectionOutOfReach
from .closed_forms import (
    comer_levy_collapse_load,
    elastica_tip,
    fichter_shear_stiffness,
    tension_field_cantilever,
)
from .dataset import CurveSpec, make_dataset, noise_floor, prescribed_deflections
from .laws import BendingLaw, law_from_moment, linear_law, reinforced_law, tension_field_law
from .scalar import (
    BAR,
    GRAVITY,
    tension_field_curvature,
    tension_field_moment,
)

__all__ = [
    "BAR",
    "GRAVITY",
    "BendingLaw",
    "CantileverModel",
    "CantileverShape",
    "CurveSpec",
    "DeflectionOutOfReach",
    "comer_levy_collapse_load",
    "elastica_tip",
    "fichter_shear_stiffness",
    "law_from_moment",
    "linear_law",
    "make_dataset",
    "noise_floor",
    "prescribed_deflections",
    "reinforced_law",
    "tension_field_cantilever",
    "tension_field_curvature",
    "tension_field_law",
    "tension_field_moment",
]
