"""Structures: tubes, their connections and supports, compiled to a static kinematic tree.

A structure is described by :class:`Tube` objects (discretised centrelines with radius,
pressure and laws), :class:`Connection` objects (nodes of different tubes that are the same
physical node) and :class:`Support` objects. :func:`build_structure` turns the description
into two objects:

- :class:`Structure`: static topology only (integer tuples). It decides shapes and the
  kinematic tree and is hashable, so ``jit`` specialises on it.
- :class:`StructureParameters`: every number (reference node positions, radii, pressures,
  laws, loads) as an immutable PyTree that ``grad``/``vmap`` can see.

Kinematic tree (Breukels & Ockels 2008: rigid segments joined by spherical joints). One
supported node is the *root*. Every segment has an *orientation parent* (a segment or the
ground frame) and a *position parent* (a segment whose end is this segment's start, or the
root). Each segment carries one joint rotation vector relative to its orientation parent:
that is the state. Further supports and closed loops are equality constraints; their joint
springs (a clamp, a loop closing through a rigid connection) are *derived joints*, whose
rotation follows from the two frames by the logarithm map.

Joint tributary lengths (docs/physics.md, section 1.2): a joint between two segments of one tube
carries half of each segment; a joint at a clamp, or where a tube is attached to another
tube, carries half of its own segment only, so its spring is twice as stiff.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import equinox as eqx
import numpy as np
from jax import Array

from .._elements import ElementParameters, ElementTopology
from .inertia import InertiaParameters

# Joint kinds (static integers): how the reference relative rotation is split.
JOINT_BEND = 0  # two segments of one tube: mid-frame split, tributary (L_a + L_b) / 2
JOINT_ATTACH = 1  # a tube attached to another tube: child frame, tributary L_child / 2
JOINT_GROUND = 2  # a segment clamped (or pinned) to the ground: tributary L / 2

GROUND = -1
STANDARD_GRAVITY = 9.81  # m/s^2

SUPPORT_KINDS = ("clamped", "pinned")
CONNECTION_KINDS = ("rigid", "pinned")


@dataclasses.dataclass(frozen=True)
class Support:
    """A support at a tube node: ``"clamped"`` (position and rotation) or ``"pinned"``
    (position only). ``node`` is ``"tube:index"`` (negative index from the end; ``start``
    and ``end`` allowed) or ``(tube, index)``."""

    node: str | tuple[str, int]
    kind: str = "clamped"


@dataclasses.dataclass(frozen=True)
class Connection:
    """Two tube nodes that are one physical node. ``"rigid"``: the attached tube's end is
    clamped into the other (a joint spring with the attached tube's law); ``"pinned"``: a
    free spherical joint."""

    node_a: str | tuple[str, int]
    node_b: str | tuple[str, int]
    kind: str = "rigid"




class SpringJointTopology(NamedTuple):
    """The joints that carry a spring, in the engine's one flat order: tree joints with a
    spring (by segment), then derived joints (further clamps, loop closures). ``J`` joints.

    Attributes:
        parent_segment: ``[J]`` int32, the segment on the parent side, or ``GROUND``.
        child_segment: ``[J]`` int32, the segment on the child side (it gives the joint
            frame).
        node: ``J`` global node indices, where each joint sits.
        law: ``J`` tube indices, whose laws the joint follows.
        kind: ``J`` joint kinds (``JOINT_BEND``, ``JOINT_ATTACH``, ``JOINT_GROUND``).
        spring_segments: the segments whose tree joint carries a spring, in tree (BFS)
            order; the first ``len(spring_segments)`` joints are theirs.
    """

    parent_segment: np.ndarray
    child_segment: np.ndarray
    node: tuple[int, ...]
    law: tuple[int, ...]
    kind: tuple[int, ...]
    spring_segments: tuple[int, ...]


class Structure(eqx.Module):
    """Static topology of a structure (hashable; decides shapes and control flow).

    Index conventions: ``S`` segments, ``N`` global nodes, ``T`` tubes, ``D`` derived joints.
    Segment ``s`` carries joint ``s`` (its joint to its orientation parent).
    """

    tube_names: tuple[str, ...] = eqx.field(static=True)
    tube_node_ids: tuple[tuple[int, ...], ...] = eqx.field(static=True)
    node_count: int = eqx.field(static=True)
    root_node: int = eqx.field(static=True)
    segment_tube: tuple[int, ...] = eqx.field(static=True)
    segment_nodes: tuple[tuple[int, int], ...] = eqx.field(static=True)  # tube direction a->b
    segment_start: tuple[int, ...] = eqx.field(static=True)  # kinematic start node
    segment_end: tuple[int, ...] = eqx.field(static=True)  # kinematic end node
    orientation_parent: tuple[int, ...] = eqx.field(static=True)  # segment or GROUND
    position_parent: tuple[int, ...] = eqx.field(static=True)  # segment or GROUND (= root)
    joint_kind: tuple[int, ...] = eqx.field(static=True)
    joint_spring: tuple[bool, ...] = eqx.field(static=True)
    joint_node: tuple[int, ...] = eqx.field(static=True)
    joint_law_tube: tuple[int, ...] = eqx.field(static=True)
    derived_frames: tuple[tuple[int, int], ...] = eqx.field(static=True)  # (a or GROUND, b)
    derived_kind: tuple[int, ...] = eqx.field(static=True)
    derived_node: tuple[int, ...] = eqx.field(static=True)
    derived_law_tube: tuple[int, ...] = eqx.field(static=True)
    node_segment: tuple[int, ...] = eqx.field(static=True)  # tree segment ending at node, or -1
    supports: tuple[tuple[int, str], ...] = eqx.field(static=True)  # (node, kind); first = root
    closures: tuple[tuple[int, int], ...] = eqx.field(static=True)  # (segment, node) pairs
    torque_nodes: tuple[int, ...] = eqx.field(static=True)  # nodes that can carry a torque
    shear: bool = eqx.field(static=True, default=False)  # segments carry shear strains
    # Point nodes, lines, pulleys, masses (jaxtube._elements); global ids N.. after tubes.
    elements: ElementTopology = eqx.field(static=True, default=ElementTopology())

    @property
    def segment_count(self) -> int:
        return len(self.segment_tube)

    def node_id(self, ref) -> int:
        """Global node index of ``"tube:index"`` / ``(tube, index)`` or of a point node's
        name (point nodes follow the tube nodes); clear error if absent."""
        if isinstance(ref, str) and ":" not in ref:
            found = self.elements.point_id(ref.strip(), self.node_count)
            if found is None:
                raise ValueError(f"node {ref!r}: no point node of that name and not a "
                                 "'tube:index' reference")
            return found
        return resolve_node(ref, self.tube_names, self.tube_node_ids)

    def spring_joint_topology(self) -> SpringJointTopology:
        """Every joint that carries a spring (free, pinned joints are left out), statically:
        see :class:`SpringJointTopology`."""
        tree = tuple(s for s, spring in enumerate(self.joint_spring) if spring)
        parent = [self.orientation_parent[s] for s in tree] + [a for a, _ in
                                                               self.derived_frames]
        child = list(tree) + [b for _, b in self.derived_frames]
        return SpringJointTopology(
            parent_segment=np.array(parent, np.int32),
            child_segment=np.array(child, np.int32),
            node=tuple(self.joint_node[s] for s in tree) + tuple(self.derived_node),
            law=tuple(self.joint_law_tube[s] for s in tree) + tuple(self.derived_law_tube),
            kind=tuple(self.joint_kind[s] for s in tree) + tuple(self.derived_kind),
            spring_segments=tree,
        )


class StructureParameters(eqx.Module):
    """Every number of a structure, as a PyTree (differentiate or ``vmap`` over any leaf).

    Attributes:
        node_position: reference node positions, shape ``[N, 3]`` [m].
        node_radius: tube radius at each node, shape ``[N]`` [m].
        pressure: envelope overpressure of each tube, shape ``[T]`` [Pa].
        bending_laws, torsion_laws: one law per tube.
        mass_per_length: per tube [kg/m]. line_load: per tube, ``[T, 3]`` [N/m].
        shear_flexibility: per tube ``u = 1 / (2 pi k G t)`` [m/N] (see :class:`Tube`);
            zeros and unused when ``Structure.shear`` is False.
        node_force: dead point forces, ``[N, 3]`` [N].
        node_torque: torques at ``Structure.torque_nodes``, ``[n_torque_nodes, 3]`` [N m].
            Which nodes can carry a torque is topology (decided when the structure is
            built), so structures without torques pay nothing for them.
        gravity: gravitational acceleration, ``[3]`` [m/s^2].
        elements: point nodes, lines, pulleys and masses (``jaxtube._elements``).
        inertia: what only the dynamics needs (enclosed and added air, line masses;
            :class:`InertiaParameters`); its defaults leave it out.
    """

    node_position: Array
    node_radius: Array
    pressure: Array
    bending_laws: tuple
    torsion_laws: tuple
    mass_per_length: Array
    line_load: Array
    node_force: Array
    node_torque: Array
    gravity: Array
    shear_flexibility: Array
    elements: ElementParameters = eqx.field(default_factory=ElementParameters)
    inertia: InertiaParameters = eqx.field(default_factory=InertiaParameters)


def _parse_node_ref(ref) -> tuple[str, int]:
    if isinstance(ref, str):
        name, sep, index = ref.rpartition(":")
        if not sep:
            raise ValueError(f"node reference {ref!r} must look like 'tube:index'")
        index = {"start": "0", "end": "-1"}.get(index.strip(), index.strip())
        try:
            return name.strip(), int(index)
        except ValueError:
            raise ValueError(f"node reference {ref!r}: index must be an integer") from None
    name, index = ref
    return str(name), int(index)


def resolve_node(ref, tube_names, tube_node_ids) -> int:
    name, index = _parse_node_ref(ref)
    if name not in tube_names:
        raise ValueError(f"node {ref!r}: no tube named {name!r} (tubes: {', '.join(tube_names)})")
    ids = tube_node_ids[tube_names.index(name)]
    if not -len(ids) <= index < len(ids):
        raise ValueError(
            f"node {ref!r} does not exist: tube {name!r} has nodes 0..{len(ids) - 1}"
        )
    return ids[index]
