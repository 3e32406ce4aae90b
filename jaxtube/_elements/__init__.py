"""Point nodes, fixed points, tension-only lines, pulleys and lumped masses (issue 14).

API (re-exported by ``jaxtube``)::

    jt.PointNode(name, position, mass=0.0, force=(0, 0, 0), at=None)   # 3 translations
    jt.FixedPoint(name, position)                                      # held; reaction out
    jt.Line(end_a, end_b, stiffness, rest_length=None, name=None)      # T = k (l - L0)+
    jt.Pulley(end_a, pulley, end_b, stiffness, rest_length=None, name=None)
    jt.PointMass(node, mass)                                           # at any node
    structure, params = jt.build_structure(tubes, supports, connections,
        points=[...], lines=[...], pulleys=[...], point_masses=[...],
        tension_smoothing=1e-4)                 # tubes and supports may be empty

Node references: a point name, ``"tube:index"``, or a global node index (tube nodes
``0..N-1``, then the structure's point nodes in declaration order: ``structure.node_id``
resolves all three). A point declared ``at`` a tube node, or placed on one, is joined to it.
Without supports the tube frame floats (its root position is an unknown), held only by lines.

Numbers live in ``params.elements`` (:class:`ElementParameters`: point positions and
forces, masses, line and pulley stiffnesses and rest lengths, the smoothing width) and
``params.gravity``; topology in ``structure.elements`` (:class:`ElementTopology`). The state
gains ``state["point_position"]`` ``[P, 3]``. ``Solution`` reports ``node_position`` for
every node (tube nodes, then point nodes), ``point_position``, ``line_tension`` [N],
``line_taut``, ``line_length``, ``pulley_tension``, ``pulley_taut``,
``fixed_point_reaction`` [N] and ``attachment_force`` [N].

Tension-only law: a C1 quadratic blend over a strain width ``delta`` around the rest length
(exact outside ``|e| < delta / 2``, tension error at most ``k L0 delta / 8``); see
``lines.py`` for why a smooth energy and not an active set.
"""

from .assembly import dense_from_blocks as dense_from_blocks
from .assembly import (
    element_constraints as element_constraints,
)
from .assembly import (
    element_energy as element_energy,
)
from .assembly import (
    element_hessian_blocks as element_hessian_blocks,
)
from .assembly import (
    element_load_potential as element_load_potential,
)
from .assembly import element_results as element_results
from .assembly import (
    element_strain_energy as element_strain_energy,
)
from .assembly import (
    initial_point_position as initial_point_position,
)
from .assembly import (
    line_report as line_report,
)
from .assembly import state_index as state_index
from .build import build_elements as build_elements
from .lines import Line as Line
from .lines import Pulley as Pulley
from .points import ElementParameters as ElementParameters
from .points import ElementTopology as ElementTopology
from .points import FixedPoint as FixedPoint
from .points import PointMass as PointMass
from .points import PointNode as PointNode
