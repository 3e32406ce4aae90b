"""The other top-level tables of a spec: supports, connections, loads, gravity, the path,
and the scalar keys (``format_version``, ``name``, ``description``)."""

from __future__ import annotations

import numpy as np

from .check import (
    array_tables,
    check_keys,
    describe,
    key_path,
    read_number,
    read_string,
    read_table,
    read_vector_key,
)
from .context import SpecContext, read_node

FORMAT_VERSION = 1
DEFAULT_STEPS = 20


def read_supports(p, value, ctx: SpecContext):
    seen = {}
    for where, table in array_tables(p, value, "support"):
        check_keys(p, table, where, ("node", "kind"), {"node": "a node name 'tube:index'"})
        ref = read_node(p, table["node"], key_path(where, "node"), ctx) if "node" in table else None
        kind = read_string(p, table, "kind", where, default="clamped",
                           choices=("clamped", "pinned"))
        if ref is not None and ref[:2] in seen:
            same = "" if ref.text == f"{ref.name}:{ref.index}" else \
                f" (= '{ref.name}:{ref.index}')"
            p.add(key_path(where, "node"), f"expected one support per node, found node "
                  f"{ref.text!r}{same} also in {seen[ref[:2]]}")
        elif ref is not None:
            seen[ref[:2]] = where
        ctx.supports.append((where, ref, kind))


def read_connections(p, value, ctx: SpecContext):
    for where, table in array_tables(p, value, "connection"):
        check_keys(p, table, where, ("nodes", "kind"),
                   {"nodes": "two node names ['tube:index', 'tube:index']"})
        kind = read_string(p, table, "kind", where, default="rigid", choices=("rigid", "pinned"))
        refs = (None, None)
        if "nodes" in table:
            nodes = table["nodes"]
            if isinstance(nodes, list) and len(nodes) == 2:
                refs = tuple(read_node(p, n, key_path(key_path(where, "nodes"), i), ctx)
                             for i, n in enumerate(nodes))
            else:
                p.add(key_path(where, "nodes"), f"expected two node names ['tube:index', "
                      f"'tube:index'], found {describe(nodes)}")
        ctx.connections.append((where, refs[0], refs[1], kind))


def read_loads(p, value, ctx: SpecContext):
    for where, table in array_tables(p, value, "load"):
        check_keys(p, table, where, ("node", "force_N", "torque_Nm"),
                   {"node": "a node name 'tube:index'"})
        ref = read_node(p, table["node"], key_path(where, "node"), ctx) if "node" in table else None
        if "force_N" not in table and "torque_Nm" not in table:
            p.add(key_path(where, "force_N"), "missing key (expected force_N and/or torque_Nm, "
                  "lists of 3 numbers [N], [N m])")
        force = read_vector_key(p, table, "force_N", where, default=(0, 0, 0))
        torque = read_vector_key(p, table, "torque_Nm", where, default=(0, 0, 0))
        ctx.loads.append((where, ref, force, torque))


def read_gravity(p, value, ctx: SpecContext):
    table = read_table(p, value, "gravity")
    if table is None:
        return
    check_keys(p, table, "gravity", ("acceleration_m_per_s2",),
               {"acceleration_m_per_s2": "a list of 3 numbers [m/s^2]"})
    ctx.gravity = read_vector_key(p, table, "acceleration_m_per_s2", "gravity")


PATH_KEYS = {
    "displacement": ("control", "node", "direction", "steps", "max_displacement_mm"),
    "force": ("control", "node", "direction", "steps", "max_load_factor"),
}


def read_path(p, value, ctx: SpecContext):
    table = read_table(p, value, "path")
    if table is None:
        return
    if "control" not in table:
        p.add("path.control", "missing required key (expected 'displacement' or 'force')")
        return
    control = read_string(p, table, "control", "path", choices=tuple(PATH_KEYS))
    if control is None:
        return
    count = len(p)
    required = {"max_displacement_mm": "a positive displacement [mm]",
                "node": "a node name 'tube:index'",
                "direction": "a non-zero list of 3 numbers"} if control == "displacement" else {}
    check_keys(p, table, "path", PATH_KEYS[control], required)
    steps = read_number(p, table, "steps", "path", default=DEFAULT_STEPS, positive=True,
                        integer=True)
    node = read_node(p, table["node"], "path.node", ctx) if "node" in table else None
    direction = read_vector_key(p, table, "direction", "path", nonzero=True)
    maximum = (read_number(p, table, "max_displacement_mm", "path", positive=True)
               if control == "displacement" else
               read_number(p, table, "max_load_factor", "path", default=1.0, positive=True))
    if control == "displacement" and node is not None:
        for where, ref, _ in ctx.supports:
            if ref is not None and ref[:2] == node[:2]:
                p.add("path.node", f"expected a node that is free to move, found the supported "
                      f"node {node.text!r} ({where})")
    if control == "force":
        loads_known = all(f is not None and t is not None for _, _, f, t in ctx.loads)
        tubes_known = all(t is not None for t in ctx.tubes)
        has_load = any(np.any(f) or np.any(t) for _, _, f, t in ctx.loads) if loads_known \
            else True
        has_line_load = any(bool(np.any(np.asarray(t.line_load))) for t in ctx.tubes) \
            if tubes_known else True
        if not has_load and not has_line_load:
            p.add("path.control", "force control scales the [[load]] forces and torques and the "
                  "tubes' line_load_N_per_m, but the spec has none (add a [[load]])")
        if "node" not in table or "direction" not in table:
            first = next(((r, f) for _, r, f, _ in ctx.loads if f is not None and np.any(f)),
                         None)
            if first is None:
                missing = "path.node" if "node" not in table else "path.direction"
                p.add(missing, "missing key (expected node and direction; they default to the "
                      "node and force direction of the first [[load]] with a force, but there "
                      "is none)")
            else:
                node = node if "node" in table else first[0]
                direction = direction if "direction" in table else first[1]
    if len(p) > count:
        return
    ctx.path = dict(control=control, steps=steps, node=node, direction=direction,
                    maximum=maximum)


def read_scalar(key, kind):
    def read(p, value, ctx):
        if kind is int and not (isinstance(value, int) and not isinstance(value, bool)):
            p.add(key, f"expected an integer, found {describe(value)}")
        elif kind is int and not 1 <= value <= FORMAT_VERSION:
            p.add(key, f"expected a format version this jaxtube reads (1..{FORMAT_VERSION}), "
                  f"found {value}; a newer jaxtube may read it")
        elif kind is str and not isinstance(value, str):
            p.add(key, f"expected a string, found {describe(value)}")
    return read
