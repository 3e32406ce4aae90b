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

Joint tributary lengths (PHYSICS.md section 1): a joint between two segments of one tube
carries half of each segment; a joint at a clamp, or where a tube is attached to another
tube, carries half of its own segment only, so its spring is twice as stiff.
"""

from __future__ import annotations

import dataclasses
from collections import deque
from collections.abc import Sequence

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._elements import (
    ElementParameters,
    ElementTopology,
    FixedPoint,
    Line,
    PointMass,
    PointNode,
    Pulley,
    build_elements,
)
from ._elements.points import DEFAULT_TENSION_SMOOTHING
from ._laws import AbstractMomentLaw

# Joint kinds (static integers): how the reference relative rotation is split.
JOINT_BEND = 0  # two segments of one tube: mid-frame split, tributary (L_a + L_b) / 2
JOINT_ATTACH = 1  # a tube attached to another tube: child frame, tributary L_child / 2
JOINT_GROUND = 2  # a segment clamped (or pinned) to the ground: tributary L / 2

GROUND = -1
STANDARD_GRAVITY = 9.81  # m/s^2

SUPPORT_KINDS = ("clamped", "pinned")
CONNECTION_KINDS = ("rigid", "pinned")


class Tube(eqx.Module):
    """One inflated tube: a discretised centreline with its section properties and laws.

    Attributes:
        name: unique name, used to refer to nodes as ``"name:index"``.
        nodes: reference centreline nodes, shape ``[n_segments + 1, 3]`` [m].
        radius: tube radius at each node, shape ``[n_segments + 1]`` [m].
        pressure: envelope overpressure [Pa].
        bending_law: moment-curvature law of bending (isotropic in the cross-section).
        torsion_law: moment-twist law of torsion; defaults to the bending law (a thin
            isotropic tube has ``GJ / EI = 1 / (1 + nu)``, so this is a rough default: give
            a torsion law whenever torsion matters).
        mass_per_length: tube mass per unit length [kg/m] (self-weight).
        line_load: uniform dead line load along the tube, world frame, shape ``[3]`` [N/m].
        shear_flexibility: ``None`` (rigid in shear, the default) or ``u = 1 / (2 pi k G t)``
            [m/N] > 0: Fichter-type shear deformation with the section shear stiffness
            ``S = p pi r^2 + k G A = p pi r^2 + r / u`` [N] (``A = 2 pi r t``; Fichter 1966,
            Le van & Wielgosz 2005; PHYSICS.md section 2). Every segment then gets a
            transverse shear strain ``gamma [2]`` with energy ``S L |gamma|^2 / 2``.
    """

    name: str = eqx.field(static=True)
    nodes: Array
    radius: Array
    pressure: Array
    bending_law: AbstractMomentLaw
    torsion_law: AbstractMomentLaw
    mass_per_length: Array
    line_load: Array
    shear_flexibility: Array | None

    def __init__(
        self,
        name: str,
        nodes,
        radius,
        pressure,
        bending_law: AbstractMomentLaw,
        torsion_law: AbstractMomentLaw | None = None,
        mass_per_length=0.0,
        line_load=(0.0, 0.0, 0.0),
        shear_flexibility=None,
    ):
        self.name = str(name)
        self.nodes = jnp.asarray(nodes, dtype=float)
        if self.nodes.ndim != 2 or self.nodes.shape[1] != 3 or self.nodes.shape[0] < 2:
            raise ValueError(f"tube {name!r}: nodes must have shape [n_segments + 1 >= 2, 3]")
        radius = jnp.asarray(radius, dtype=float)
        self.radius = jnp.broadcast_to(radius, self.nodes.shape[:1])
        self.pressure = jnp.asarray(pressure, dtype=float)
        self.bending_law = bending_law
        self.torsion_law = torsion_law if torsion_law is not None else bending_law
        self.mass_per_length = jnp.asarray(mass_per_length, dtype=float)
        self.line_load = jnp.asarray(line_load, dtype=float)
        self.shear_flexibility = (None if shear_flexibility is None
                                  else jnp.asarray(shear_flexibility, dtype=float))

    @property
    def n_segments(self) -> int:
        return self.nodes.shape[0] - 1


def _radius_profile(radius, fractions: np.ndarray) -> np.ndarray:
    """Radius at arc-length fractions: a scalar, or ``[(fraction, radius), ...]`` pairs."""
    table = np.asarray(radius, dtype=float)
    if table.ndim == 0:
        return np.full_like(fractions, float(table))
    if table.ndim != 2 or table.shape[1] != 2:
        raise ValueError("radius must be a number or a list of [fraction, radius] pairs")
    return np.interp(fractions, table[:, 0], table[:, 1])


def straight_tube(name, start, end, segments, radius, pressure, bending_law, **kwargs) -> Tube:
    """A straight tube from ``start`` to ``end`` [m] cut into ``segments`` equal segments.

    ``radius`` is a number [m] or ``[(fraction_of_length, radius_m), ...]`` for a taper.
    Remaining keyword arguments go to :class:`Tube`.
    """
    fractions = np.linspace(0.0, 1.0, int(segments) + 1)
    start, end = np.asarray(start, float), np.asarray(end, float)
    nodes = start[None, :] + fractions[:, None] * (end - start)[None, :]
    return Tube(name, nodes, _radius_profile(radius, fractions), pressure, bending_law, **kwargs)


def arc_tube(
    name, centre, arc_radius, start_angle, end_angle, segments, radius, pressure, bending_law,
    normal=(0.0, 0.0, 1.0), reference=(1.0, 0.0, 0.0), **kwargs,
) -> Tube:
    """A circular-arc tube: ``centre + R (cos phi u + sin phi v)``, ``phi`` from start to end.

    ``u`` is ``reference`` made orthogonal to ``normal`` (the arc plane's normal) and
    ``v = normal x u``. Angles in radians, lengths in m.
    """
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    u = np.asarray(reference, float)
    u = u - normal * (u @ normal)
    u = u / np.linalg.norm(u)
    v = np.cross(normal, u)
    fractions = np.linspace(0.0, 1.0, int(segments) + 1)
    phi = start_angle + fractions * (end_angle - start_angle)
    nodes = np.asarray(centre, float)[None, :] + arc_radius * (
        np.cos(phi)[:, None] * u[None, :] + np.sin(phi)[:, None] * v[None, :]
    )
    return Tube(name, nodes, _radius_profile(radius, fractions), pressure, bending_law, **kwargs)


def polyline_tube(name, points, segments, radius, pressure, bending_law, **kwargs) -> Tube:
    """A tube along a polyline through ``points`` [m], resampled at equal arc length."""
    points = np.asarray(points, float)
    lengths = np.linalg.norm(np.diff(points, axis=0), axis=1)
    if np.any(lengths <= 0.0):
        raise ValueError(f"tube {name!r}: polyline has repeated points")
    arc = np.concatenate([[0.0], np.cumsum(lengths)])
    fractions = np.linspace(0.0, 1.0, int(segments) + 1)
    target = fractions * arc[-1]
    nodes = np.stack([np.interp(target, arc, points[:, k]) for k in range(3)], axis=1)
    return Tube(name, nodes, _radius_profile(radius, fractions), pressure, bending_law, **kwargs)


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
        return _resolve_node(ref, self.tube_names, self.tube_node_ids)



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


def _resolve_node(ref, tube_names, tube_node_ids) -> int:
    name, index = _parse_node_ref(ref)
    if name not in tube_names:
        raise ValueError(f"node {ref!r}: no tube named {name!r} (tubes: {', '.join(tube_names)})")
    ids = tube_node_ids[tube_names.index(name)]
    if not -len(ids) <= index < len(ids):
        raise ValueError(
            f"node {ref!r} does not exist: tube {name!r} has nodes 0..{len(ids) - 1}"
        )
    return ids[index]


def build_structure(
    tubes: Sequence[Tube],
    supports: Sequence[Support],
    connections: Sequence[Connection] = (),
    node_force=None,
    node_torque=None,
    gravity=(0.0, 0.0, -STANDARD_GRAVITY),
    merge_tolerance: float = 1e-9,
    points: Sequence[PointNode | FixedPoint] = (),
    lines: Sequence[Line] = (),
    pulleys: Sequence[Pulley] = (),
    point_masses: Sequence[PointMass] = (),
    tension_smoothing: float = DEFAULT_TENSION_SMOOTHING,
) -> tuple[Structure, StructureParameters]:
    """Compile tubes, connections and supports into a :class:`Structure` and its parameters.

    ``node_force``/``node_torque`` may be given as ``{node_ref: [fx, fy, fz]}`` dictionaries
    (N, N m) or as full ``[N, 3]`` arrays. Every node named in ``node_torque`` (or with a
    non-zero row) can carry a torque; give a zero torque to declare one for later.

    Point nodes, fixed points, tension-only lines, pulleys and point masses
    (``jaxtube._elements``) join through ``points``, ``lines``, ``pulleys`` and
    ``point_masses``; ``tension_smoothing`` is the strain width of the lines' slack-taut
    blend. Without supports the tube frame floats (its root is node 0 of the first tube,
    position unknown), held by lines; a structure may also have no tube at all.

    Raises ``ValueError`` with a clear message for a duplicate tube name, an unknown node,
    non-coincident connected nodes, an unknown kind, a structure that is not connected, or
    a bad element (``jaxtube._elements.build``).
    """
    tubes = list(tubes)
    names = tuple(t.name for t in tubes)
    if len(set(names)) != len(names):
        raise ValueError(f"tube names must be unique, got {names}")
    element_args = (points, lines, pulleys, point_masses, merge_tolerance, tension_smoothing)
    if not tubes:
        if supports or connections:
            raise ValueError("supports and connections need tubes")
        return _points_only_structure(gravity, element_args)
    for tube in tubes:
        if not bool(jnp.all(tube.radius > 0)):
            raise ValueError(f"tube {tube.name!r}: radius must be positive")
    # Local node numbering, then merge connected nodes (union-find).
    offsets = np.cumsum([0] + [t.nodes.shape[0] for t in tubes])
    local_ids = tuple(tuple(range(offsets[i], offsets[i + 1])) for i in range(len(tubes)))
    all_nodes = np.concatenate([np.asarray(t.nodes) for t in tubes])
    all_radius = np.concatenate([np.asarray(t.radius) for t in tubes])
    parent = list(range(len(all_nodes)))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    connection_kind = {}
    for conn in connections:
        if conn.kind not in CONNECTION_KINDS:
            raise ValueError(f"connection kind {conn.kind!r}: expected one of {CONNECTION_KINDS}")
        a = _resolve_node(conn.node_a, names, local_ids)
        b = _resolve_node(conn.node_b, names, local_ids)
        gap = np.linalg.norm(all_nodes[a] - all_nodes[b])
        if gap > merge_tolerance * max(1.0, np.abs(all_nodes).max()):
            raise ValueError(
                f"connection {conn.node_a!r} - {conn.node_b!r}: nodes are {gap:.3g} m apart; "
                "connected nodes must coincide"
            )
        parent[find(b)] = find(a)
        connection_kind[find(a)] = conn.kind
    roots = sorted({find(i) for i in range(len(all_nodes))})
    global_of = {r: k for k, r in enumerate(roots)}
    to_global = [global_of[find(i)] for i in range(len(all_nodes))]
    node_count = len(roots)
    tube_node_ids = tuple(tuple(to_global[i] for i in ids) for ids in local_ids)
    pinned_nodes = {global_of[find(r)] for r, k in connection_kind.items() if k == "pinned"}
    position = np.zeros((node_count, 3))
    radius = np.zeros(node_count)
    for i, g in enumerate(to_global):
        position[g] = all_nodes[i]
        radius[g] = max(radius[g], all_radius[i])

    # Segments in tube order; material direction a -> b along the tube.
    seg_tube, seg_nodes, seg_local = [], [], []
    for t, ids in enumerate(tube_node_ids):
        for k in range(len(ids) - 1):
            seg_tube.append(t)
            seg_nodes.append((ids[k], ids[k + 1]))
            seg_local.append(k)
    incident = [[] for _ in range(node_count)]
    for s, (a, b) in enumerate(seg_nodes):
        if a == b:
            raise ValueError(f"tube {names[seg_tube[s]]!r}: zero-length segment {seg_local[s]}")
        incident[a].append(s)
        incident[b].append(s)

    support_list = []
    for sup in supports:
        if sup.kind not in SUPPORT_KINDS:
            raise ValueError(f"support kind {sup.kind!r}: expected one of {SUPPORT_KINDS}")
        support_list.append((_resolve_node(sup.node, names, tube_node_ids), sup.kind))
    if len({n for n, _ in support_list}) != len(support_list):
        raise ValueError("two supports on the same node")
    support_kind = dict(support_list)
    # No support: a floating frame (held by lines); its root is node 0 of the first tube.
    root, root_kind = support_list[0] if support_list else (tube_node_ids[0][0], "free")

    def adjacent_same_tube(s1, s2):
        return seg_tube[s1] == seg_tube[s2] and abs(seg_local[s1] - seg_local[s2]) == 1

    # BFS building the kinematic tree.  Segments get new ids in BFS order so that every
    # parent precedes its children.
    order: list[int] = []
    new_id: dict[int, int] = {}
    o_parent, p_parent, kinds, springs, jnode, jlaw, starts, ends = ([] for _ in range(8))
    derived_frames, derived_kind, derived_node, derived_law = [], [], [], []
    closures = []
    node_segment = [-1] * node_count
    visited_nodes = {root}

    def add_segment(s, start, o_par, p_par, kind, spring):
        new_id[s] = len(order)
        order.append(s)
        a, b = seg_nodes[s]
        end = b if start == a else a
        o_parent.append(o_par)
        p_parent.append(p_par)
        kinds.append(kind)
        springs.append(spring)
        jnode.append(start)
        jlaw.append(seg_tube[s])
        starts.append(start)
        ends.append(end)
        return end

    def clamp_cut(node) -> bool:
        return node != root and support_kind.get(node) == "clamped"

    queue = deque()
    root_segments = incident[root]
    if not root_segments:
        raise ValueError("the root support's node has no segment")
    if root_kind == "clamped":
        for s in root_segments:
            end = add_segment(s, root, GROUND, GROUND, JOINT_GROUND, True)
            queue.append((end, s))
    else:
        first = root_segments[0]
        queue.append((add_segment(first, root, GROUND, GROUND, JOINT_GROUND, False), first))
        for s in root_segments[1:]:
            kind = JOINT_BEND if adjacent_same_tube(first, s) else JOINT_ATTACH
            spring = root not in pinned_nodes
            queue.append((add_segment(s, root, new_id[first], GROUND, kind, spring), s))
    while queue:
        node, via = queue.popleft()
        if node in visited_nodes:
            # Loop closure: this segment's end meets a node already placed.
            closures.append((new_id[via], node))
            other = node_segment[node] if node_segment[node] >= 0 else None
            if node not in pinned_nodes:
                a = GROUND if other is None else other
                kind = JOINT_BEND if other is not None and adjacent_same_tube(
                    order[other], via) else JOINT_ATTACH
                derived_frames.append((a, new_id[via]))
                derived_kind.append(kind)
                derived_node.append(node)
                derived_law.append(seg_tube[via])
            continue
        visited_nodes.add(node)
        node_segment[node] = new_id[via]
        cut = clamp_cut(node)
        if cut:
            derived_frames.append((GROUND, new_id[via]))
            derived_kind.append(JOINT_GROUND)
            derived_node.append(node)
            derived_law.append(seg_tube[via])
        pending = [s for s in incident[node] if s not in new_id]
        # A tube passing through the node continues from the same-tube neighbour first.
        pending.sort(key=lambda s: (not adjacent_same_tube(via, s), seg_tube[s], seg_local[s]))
        placed_here: list[int] = []
        for s in pending:
            if cut:
                end = add_segment(s, node, GROUND, new_id[via], JOINT_GROUND, True)
            else:
                host = via
                if not adjacent_same_tube(via, s):
                    # Pass-through tube attached here: its second segment bends off its first.
                    for q in placed_here:
                        if adjacent_same_tube(q, s):
                            host = q
                            break
                kind = JOINT_BEND if adjacent_same_tube(host, s) else JOINT_ATTACH
                spring = node not in pinned_nodes or kind == JOINT_BEND
                end = add_segment(s, node, new_id[host], new_id[via], kind, spring)
            placed_here.append(s)
            queue.append((end, s))
    if len(order) != len(seg_nodes):
        missing = sorted({names[seg_tube[s]] for s in range(len(seg_nodes)) if s not in new_id})
        raise ValueError(f"tubes {missing} are not connected to the supported structure")
    for n, kind in support_list[1:]:
        if node_segment[n] < 0:
            raise ValueError(f"support at node {n} is not reached by the structure")

    structure = Structure(
        tube_names=names,
        tube_node_ids=tube_node_ids,
        node_count=node_count,
        root_node=root,
        segment_tube=tuple(seg_tube[s] for s in order),
        segment_nodes=tuple(seg_nodes[s] for s in order),
        segment_start=tuple(starts),
        segment_end=tuple(ends),
        orientation_parent=tuple(o_parent),
        position_parent=tuple(p_parent),
        joint_kind=tuple(kinds),
        joint_spring=tuple(springs),
        joint_node=tuple(jnode),
        joint_law_tube=tuple(jlaw),
        derived_frames=tuple(derived_frames),
        derived_kind=tuple(derived_kind),
        derived_node=tuple(derived_node),
        derived_law_tube=tuple(derived_law),
        node_segment=tuple(node_segment),
        supports=tuple(support_list),
        closures=tuple(closures),
        torque_nodes=(),
    )
    force = _node_array(node_force, structure, "node_force")
    torque = _node_array(node_torque, structure, "node_torque")
    if isinstance(node_torque, dict):
        torque_nodes = sorted({structure.node_id(ref) for ref in node_torque})
    else:
        torque_nodes = [int(n) for n in np.flatnonzero(np.any(np.asarray(torque) != 0, axis=1))]
    for n in torque_nodes:
        if structure.node_segment[n] < 0:
            raise ValueError(f"node {n} is the root support: a torque there does no work")
    with_shear = [t.shear_flexibility is not None for t in tubes]
    if any(with_shear) and not all(with_shear):
        missing = [t.name for t in tubes if t.shear_flexibility is None]
        raise ValueError("shear deformation must be given for every tube or for none (tubes "
                         f"without shear_flexibility: {missing})")
    topology, element_params, alias_forces = build_elements(
        structure, position, *element_args)
    for node, extra in alias_forces.items():
        force = force.at[node].add(jnp.asarray(extra))
    structure = dataclasses.replace(structure, torque_nodes=tuple(torque_nodes),
                                    shear=all(with_shear), elements=topology)
    torque = torque[np.array(torque_nodes, dtype=np.int32)] if torque_nodes else jnp.zeros((0, 3))
    params = StructureParameters(
        node_position=jnp.asarray(position),
        node_radius=jnp.asarray(radius),
        pressure=jnp.stack([t.pressure for t in tubes]),
        bending_laws=tuple(t.bending_law for t in tubes),
        torsion_laws=tuple(t.torsion_law for t in tubes),
        mass_per_length=jnp.stack([t.mass_per_length for t in tubes]),
        line_load=jnp.stack([jnp.broadcast_to(t.line_load, (3,)) for t in tubes]),
        node_force=force,
        node_torque=torque,
        gravity=jnp.asarray(gravity, dtype=float),
        shear_flexibility=jnp.stack([jnp.asarray(0.0) if t.shear_flexibility is None
                                     else t.shear_flexibility for t in tubes]),
        elements=element_params,
    )
    return structure, params


def _points_only_structure(gravity, element_args) -> tuple[Structure, StructureParameters]:
    """A structure of point nodes, lines and pulleys only (no tube, no segment)."""
    empty = Structure(
        tube_names=(), tube_node_ids=(), node_count=0, root_node=GROUND, segment_tube=(),
        segment_nodes=(), segment_start=(), segment_end=(), orientation_parent=(),
        position_parent=(), joint_kind=(), joint_spring=(), joint_node=(), joint_law_tube=(),
        derived_frames=(), derived_kind=(), derived_node=(), derived_law_tube=(),
        node_segment=(), supports=(), closures=(), torque_nodes=(),
    )
    topology, element_params, _ = build_elements(empty, np.zeros((0, 3)), *element_args)
    structure = dataclasses.replace(empty, elements=topology)
    params = StructureParameters(
        node_position=jnp.zeros((0, 3)), node_radius=jnp.zeros((0,)), pressure=jnp.zeros((0,)),
        bending_laws=(), torsion_laws=(), mass_per_length=jnp.zeros((0,)),
        line_load=jnp.zeros((0, 3)), node_force=jnp.zeros((0, 3)),
        node_torque=jnp.zeros((0, 3)), gravity=jnp.asarray(gravity, dtype=float),
        shear_flexibility=jnp.zeros((0,)), elements=element_params,
    )
    return structure, params


def _node_array(values, structure: Structure, what: str) -> Array:
    out = np.zeros((structure.node_count, 3))
    if values is None:
        return jnp.asarray(out)
    if isinstance(values, dict):
        for ref, vec in values.items():
            out[structure.node_id(ref)] += np.asarray(vec, float)
        return jnp.asarray(out)
    arr = jnp.asarray(values, dtype=float)
    if arr.shape != out.shape:
        raise ValueError(f"{what} must have shape {out.shape}, got {arr.shape}")
    return arr


def cantilever(
    length: float,
    radius,
    pressure: float,
    segments: int,
    bending_law: AbstractMomentLaw,
    torsion_law: AbstractMomentLaw | None = None,
    direction=(1.0, 0.0, 0.0),
    origin=(0.0, 0.0, 0.0),
    mass_per_length: float = 0.0,
    name: str = "tube",
    shear_flexibility=None,
) -> tuple[Structure, StructureParameters]:
    """A straight tube clamped at its start: the standard bench test of PHYSICS.md.

    The tip is node ``"tube:end"``. ``direction`` is the tube axis (any direction).
    """
    direction = np.asarray(direction, float)
    direction = direction / np.linalg.norm(direction)
    origin = np.asarray(origin, float)
    tube = straight_tube(
        name, origin, origin + length * direction, segments, radius, pressure, bending_law,
        torsion_law=torsion_law,
        mass_per_length=mass_per_length, shear_flexibility=shear_flexibility,
    )
    return build_structure([tube], [Support(f"{name}:0", "clamped")])
