"""What the spec readers gather as they go (:class:`SpecContext`), and node names.

Each table reader checks one top-level entry and adds to the context; node names
(``"tube:index"``, or a kite's ``le:centre``) are checked against the tubes read so far.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from .._structure.kite import KITE_NODE_NAMES
from .check import describe, suggest


@dataclasses.dataclass
class SpecContext:
    tubes: list = dataclasses.field(default_factory=list)  # Tube or None per [[tube]]
    tube_nodes: dict = dataclasses.field(default_factory=dict)  # name -> node count or None
    supports: list = dataclasses.field(default_factory=list)  # (where, ref, kind)
    connections: list = dataclasses.field(default_factory=list)  # (where, ref_a, ref_b, kind)
    loads: list = dataclasses.field(default_factory=list)  # (where, ref, force, torque)
    gravity: np.ndarray | None = None
    path: dict | None = None
    dynamics: object = None  # DynamicsSpec of a [dynamics] table
    tube_names_known: bool = True  # False when a tube name is missing or invalid
    node_aliases: dict = dataclasses.field(default_factory=dict)  # "le:centre" -> "le:12"


class NodeRef(NamedTuple):
    name: str  # tube name
    index: int  # node index along the tube, >= 0
    text: str  # as written in the spec


def read_node(p, value, where, ctx: SpecContext) -> NodeRef | None:
    """A node name checked against the tubes, or None. Kite node names (``le:centre``)
    stand for the ``tube:index`` in ``ctx.node_aliases``; ``text`` keeps what was written."""
    if isinstance(value, str) and value.strip() in ctx.node_aliases:
        node = read_node(p, ctx.node_aliases[value.strip()], where, ctx)
        return None if node is None else node._replace(text=value)
    if not isinstance(value, str):
        p.add(where, f"expected a node name 'tube:index' (e.g. 'beam:end'), found "
              f"{describe(value)}")
        return None
    name, sep, index_text = value.rpartition(":")
    name, index_text = name.strip(), index_text.strip()
    index_text = {"start": "0", "end": "-1"}.get(index_text, index_text)
    try:
        index = int(index_text)
    except ValueError:
        index = None
    if not sep or index is None:
        if not ctx.tube_names_known and index_text in KITE_NODE_NAMES:
            return None  # a kite node of a [kite] whose problems are already reported
        p.add(where, f"expected a node name 'tube:index' (index an integer, negative from the "
              f"end, or 'start'/'end'), found {value!r}")
        return None
    if name not in ctx.tube_nodes:
        if not ctx.tube_names_known:  # it may be the tube whose name is already reported
            return None
        tubes = ", ".join(repr(t) for t in ctx.tube_nodes) or "none"
        p.add(where, f"node {value!r} does not exist: no tube named {name!r}"
              f"{suggest(name, ctx.tube_nodes)} (tubes: {tubes})")
        return None
    count = ctx.tube_nodes[name]
    if count is None:  # the tube's segment count is already reported as a problem
        return None
    if not -count <= index < count:
        p.add(where, f"node {value!r} does not exist: tube {name!r} has nodes 0..{count - 1} "
              f"(or -{count}..-1 from the end, 'start', 'end')")
        return None
    return NodeRef(name, index % count, value)
