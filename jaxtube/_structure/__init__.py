"""Structures: tubes, their connections and supports, compiled to a static kinematic tree.

- :mod:`.tube`: one tube and its centreline generators;
- :mod:`.structure`: the static topology (:class:`Structure`, with its spring-joint
  topology), every number (:class:`StructureParameters`), supports and connections;
- :mod:`.inertia`: what only the dynamics needs (:class:`InertiaParameters`);
- :mod:`.build`: :func:`build_structure` and :func:`cantilever`;
- :mod:`.kite`: parametric tube kites (:class:`TubeKite`).
"""

from .build import build_structure as build_structure
from .build import cantilever as cantilever
from .inertia import InertiaParameters as InertiaParameters
from .inertia import air_density as air_density
from .kite import KITE_NODE_NAMES as KITE_NODE_NAMES
from .kite import LEADING_EDGE as LEADING_EDGE
from .kite import Strut as Strut
from .kite import TubeKite as TubeKite
from .kite import arc_through_tips as arc_through_tips
from .kite import double_taper as double_taper
from .structure import GROUND as GROUND
from .structure import JOINT_ATTACH as JOINT_ATTACH
from .structure import JOINT_BEND as JOINT_BEND
from .structure import JOINT_GROUND as JOINT_GROUND
from .structure import STANDARD_GRAVITY as STANDARD_GRAVITY
from .structure import Connection as Connection
from .structure import SpringJointTopology as SpringJointTopology
from .structure import Structure as Structure
from .structure import StructureParameters as StructureParameters
from .structure import Support as Support
from .tube import Tube as Tube
from .tube import arc_tube as arc_tube
from .tube import polyline_tube as polyline_tube
from .tube import straight_tube as straight_tube
