"""Kinematics and total potential energy of a rigid-segment tube structure.

State (a PyTree, so that new kinds of degrees of freedom can join later)::

    {"root_position": [3] m, "segment_rotation": [S, 3] rad}

``segment_rotation[s] = phi_s`` is the rotation of rigid segment ``s`` from its reference
orientation, in its material frame: ``Q_s = Q_s0 exp(phi_s)``. The joint rotation of a
spherical joint between segments ``a`` (parent) and ``b`` follows from the two, in the joint
frame (its third axis is the tube axis there, so its first two components are bending and
the third is torsion; Breukels & Ockels 2008)::

    exp(theta) = H_pre^T Q_a^T Q_b H_post^T = exp(-H_pre^T phi_a) exp(H_post phi_b)

where ``H_pre H_post = Q_a0^T Q_b0`` is the reference relative rotation. Between two segments
of one tube ``H_pre = H_post`` = half the reference bend (the joint frame bisects the two
axes, so an arc's bending and torsion are split symmetrically); where a tube is attached to
another, ``H_pre`` is the whole reference rotation and the joint frame is the attached tube's.

Why segment rotations rather than joint rotations as unknowns: node positions are then sums
of independent per-segment terms ``Q_s0 exp(phi_s) e_s``, so every load and every support
or control constraint is separable by segment, and each spring couples only its two
segments. The Hessian of the Lagrangian is block-sparse along the joints and is assembled
from small element Hessians (:func:`jaxtube._mechanics.hessian.lagrangian_hessian`) instead of
pushing every unknown through the whole chain. The model (its energy and its equilibria) is
the same; only the coordinates differ.

Energy (per unit length laws, docs/physics.md, sections 1.2 and 1.3): joint ``j`` with
rotation ``theta`` and tributary length ``l`` has curvature ``kappa = theta / l`` and energy
``l [W_bend(kappa_1^2 + kappa_2^2) + W_twist(kappa_3^2)]``, isotropic in the cross-section.
Loads are dead: point forces and torques, uniform line loads and self-weight (lumped at
segment midpoints, which is exact for a rigid segment).
"""

from .energy import energy_and_constraints as energy_and_constraints
from .energy import energy_terms_and_constraints as energy_terms_and_constraints
from .energy import joint_moments as joint_moments
from .energy import segment_loads as segment_loads
from .energy import total_energy as total_energy
from .geometry import ReferenceGeometry as ReferenceGeometry
from .geometry import reference_geometry as reference_geometry
from .hessian import lagrangian_hessian as lagrangian_hessian
from .hessian import lagrangian_hessian_blocks as lagrangian_hessian_blocks
from .kinematics import Configuration as Configuration
from .kinematics import configuration as configuration
from .kinematics import initial_state as initial_state
from .kinematics import spring_joints as spring_joints
