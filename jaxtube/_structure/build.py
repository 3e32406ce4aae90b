"""Compiling tubes, connections and supports into a :class:`Structure` and its parameters.

:func:`build_structure` numbers the nodes (merging connected ones), builds the kinematic
tree by a breadth-first walk from the root support, and records the derived joints (further
clamps, loop closures); :func:`cantilever` is the standard bench structure.
"""

from __future__ import annotations

import dataclasses
from collections import deque
from collections.abc import Sequence

import jax.numpy as jnp
import numpy as np
from jax import Array

from .._elements import FixedPoint, Line, PointMass, PointNode, Pulley, build_elements
from .._elements.points import DEFAULT_TENSION_SMOOTHING
from .._laws import AbstractMomentLaw
from .structure import (
    CONNECTION_KINDS,
    GROUND,
    JOINT_ATTACH,
    JOINT_BEND,
    JOINT_GROUND,
    STANDARD_GRAVITY,
    SUPPORT_KINDS,
    Connection,
    Structure,
    StructureParameters,
    Support,
    resolve_node,
)
from .tube import Tube, straight_tube


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
        a = resolve_node(conn.node_a, names, local_ids)
        b = resolve_node(conn.node_b, names, local_ids)
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
        support_list.append((resolve_node(sup.node, names, tube_node_ids), sup.kind))
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
    """A straight tube clamped at its start: the standard bench test (docs/physics.md,
    section 1.1).

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
