"""Spec tables of point nodes, lines, pulleys, canopies and point masses.

Keys (reference; the spec format as a whole is in docs/spec-format.md)::

    [[point]]                          # a point node: three translations, no rotation
    name = "bridle"                    # required, unique, no ":"
    position_m = [0, 0, 1.5]           # required: reference position (initial guess)
    fixed = false                      # optional: true holds it in space (a suspension)
    mass_kg = 0.0                      # optional, >= 0: lumped mass under gravity
    force_N = [0, 0, 0]                # optional: dead point force

    [[line]]                           # a tension-only line: k (l - L0) when taut, else 0
    nodes = ["bridle", "le:centre"]    # required: two point names or tube nodes
    stiffness_N_per_m = 5000           # required, positive
    rest_length_m = 1.2                # optional, positive; default the reference distance
    name = "front line"                # optional label

    [[pulley]]                         # one rope over a pulley node: one tension both sides
    nodes = ["a", "pulley", "b"]       # required: rope end, pulley node, rope end
    stiffness_N_per_m = 5000           # required, positive (the whole rope)
    rest_length_m = 2.0                # optional, positive; default the reference l1 + l2
    name = "..."                       # optional

    [[canopy]]                         # a membrane as a net of tension-only lines
    name = "canopy"                    # required, unique
    grid = [["le:0", "le:1", "le:2"],  # required: rows of node names (>= 2 rows of >= 2,
            ["te0", "te1", "te2"]]     #   all rows the same length, names unique)
    stiffness_N_per_m = 2000           # required, positive: every line of the net
    diagonals = true                   # optional: both diagonals of every cell (default)
    rest_length_factor = 1.0           # optional, positive: rest length / reference length

    [[point_mass]]                     # a lumped mass at any node (point or tube node)
    node = "le:centre"                 # required
    mass_kg = 0.5                      # required, positive

A node is a ``[[point]]`` name or a tube node ``"tube:index"`` (kite names such as
``le:centre`` too). The canopy's lines run along the rows, along the columns and (with
``diagonals``) across each cell both ways, as kite_fem's canopy; they are named
``"canopy <name> (row,col)-(row,col)"``. Without ``[[support]]`` the tube frame floats,
held by lines to fixed points; gravity then defaults to ``[0, 0, -9.81]`` if anything has
mass. Every problem is reported with its key path, what was expected and what was found.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._elements import FixedPoint, Line, PointMass, PointNode, Pulley
from .check import (
    check_keys,
    describe,
    key_path,
    read_number,
    read_string,
    read_table,
    read_vector_key,
    suggest,
)
from .context import read_node

ELEMENT_TABLES = ("point", "line", "pulley", "canopy", "point_mass")


@dataclasses.dataclass
class ElementSpec:
    """What the element tables of a spec hold (filled by :func:`read_element_tables`)."""

    points: list = dataclasses.field(default_factory=list)  # PointNode | FixedPoint
    lines: list = dataclasses.field(default_factory=list)
    pulleys: list = dataclasses.field(default_factory=list)
    point_masses: list = dataclasses.field(default_factory=list)
    point_positions: dict = dataclasses.field(default_factory=dict)  # name -> [3]
    fixed: bool = False  # a fixed point exists

    @property
    def has_mass(self) -> bool:
        return bool(self.point_masses) or any(
            isinstance(pt, PointNode) and pt.mass > 0 for pt in self.points)

    def build_arguments(self) -> dict:
        """Keyword arguments of ``build_structure``."""
        return dict(points=self.points, lines=self.lines, pulleys=self.pulleys,
                    point_masses=self.point_masses)


def _node(p, value, where, ctx, spec: ElementSpec):
    """A point name or a tube node (``"tube:index"``); the reference or None."""
    if isinstance(value, str) and ":" not in value and value.strip() not in ctx.node_aliases:
        name = value.strip()
        if name in spec.point_positions:
            return name
        known = ", ".join(repr(n) for n in spec.point_positions) or "none"
        p.add(where, f"node {value!r} does not exist: no [[point]] named {name!r}"
              f"{suggest(name, spec.point_positions)} (points: {known}; tube nodes are "
              "named 'tube:index')")
        return None
    ref = read_node(p, value, where, ctx)
    return None if ref is None else f"{ref.name}:{ref.index}"


def _nodes(p, table, where, ctx, spec, count: int, what: str):
    key_where = key_path(where, "nodes")
    if "nodes" not in table:
        return None
    value = table["nodes"]
    if not (isinstance(value, list) and len(value) == count):
        p.add(key_where, f"expected {what}, found {describe(value)}")
        return None
    refs = [_node(p, v, key_path(key_where, i), ctx, spec) for i, v in enumerate(value)]
    if any(r is None for r in refs):
        return None
    if len(set(refs)) != len(refs):
        p.add(key_where, f"expected {count} different nodes, found {describe(value)}")
        return None
    return refs


def _read_points(p, value, ctx, spec: ElementSpec):
    tables = read_table(p, value, "point", array=True)
    if tables is None:
        return
    for index, table in enumerate(tables):
        where = key_path("point", index)
        check_keys(p, table, where, ("name", "position_m", "fixed", "mass_kg", "force_N"),
                   {"name": "a point name (no ':')",
                       "position_m": "a list of 3 numbers [m]"})
        name = read_string(p, table, "name", where)
        if name is not None and (not name.strip() or ":" in name):
            p.add(key_path(where, "name"), f"expected a non-empty name without ':' (that marks "
                  f"a tube node 'tube:index'), found {name!r}")
            name = None
        elif name is not None and name.strip() in spec.point_positions:
            p.add(key_path(where, "name"), f"expected a unique point name, found {name!r} twice")
            name = None
        position = read_vector_key(p, table, "position_m", where)
        fixed = table.get("fixed", False)
        if not isinstance(fixed, bool):
            p.add(key_path(where, "fixed"), f"expected true or false, found {describe(fixed)}")
            fixed = None
        mass = read_number(p, table, "mass_kg", where, default=0.0, minimum=0.0)
        force = read_vector_key(p, table, "force_N", where, default=(0, 0, 0))
        if fixed and ("mass_kg" in table or "force_N" in table):
            p.add(where, "a fixed point takes no mass_kg or force_N (its reaction carries "
                  "whatever reaches it; put masses on the nodes that move)")
            continue
        if name is None or position is None or fixed is None or mass is None or force is None:
            continue
        name = name.strip()
        spec.point_positions[name] = position
        if fixed:
            spec.points.append(FixedPoint(name, position))
            spec.fixed = True
        else:
            spec.points.append(PointNode(name, position, mass=float(mass), force=force))


def _read_ropes(p, value, ctx, spec: ElementSpec, key: str, what: str, make):
    """``[[line]]`` (two nodes) or ``[[pulley]]`` (three): nodes, stiffness, rest length,
    name; ``make(refs, stiffness, rest, name)`` builds the element."""
    tables = read_table(p, value, key, array=True)
    if tables is None:
        return
    count = 2 if key == "line" else 3
    for index, table in enumerate(tables):
        where = key_path(key, index)
        check_keys(p, table, where, ("nodes", "stiffness_N_per_m", "rest_length_m", "name"),
                   {"nodes": what, "stiffness_N_per_m": "a positive number"})
        refs = _nodes(p, table, where, ctx, spec, count, what)
        stiffness = read_number(p, table, "stiffness_N_per_m", where, positive=True)
        rest = read_number(p, table, "rest_length_m", where, default=None, positive=True)
        name = read_string(p, table, "name", where, default=where)
        if refs is None or stiffness is None or name is None or (
                "rest_length_m" in table and rest is None):
            continue
        make(refs, float(stiffness), rest, name)


def _read_lines(p, value, ctx, spec: ElementSpec):
    _read_ropes(p, value, ctx, spec, "line", "two node names [a, b]",
                lambda refs, k, rest, name: spec.lines.append(
                    Line(refs[0], refs[1], k, rest, name=name)))


def _read_pulleys(p, value, ctx, spec: ElementSpec):
    _read_ropes(p, value, ctx, spec, "pulley", "three node names [end, pulley, end]",
                lambda refs, k, rest, name: spec.pulleys.append(
                    Pulley(refs[0], refs[1], refs[2], k, rest, name=name)))


def _reference_position(ref: str, ctx, spec: ElementSpec):
    if ref in spec.point_positions:
        return np.asarray(spec.point_positions[ref], dtype=float)
    name, _, index = ref.rpartition(":")
    for tube in ctx.tubes:
        if tube is not None and tube.name == name:
            return np.asarray(tube.nodes[int(index)], dtype=float)
    return None


def _read_canopies(p, value, ctx, spec: ElementSpec):
    tables = read_table(p, value, "canopy", array=True)
    if tables is None:
        return
    names = set()
    for index, table in enumerate(tables):
        where = key_path("canopy", index)
        check_keys(p, table, where, ("name", "grid", "stiffness_N_per_m", "diagonals",
                                     "rest_length_factor"),
                   {"name": "a canopy name", "grid": "rows of node names",
                    "stiffness_N_per_m": "a positive number"})
        name = read_string(p, table, "name", where)
        if name is not None and name in names:
            p.add(key_path(where, "name"), f"expected a unique canopy name, found {name!r} twice")
            name = None
        names.add(name)
        stiffness = read_number(p, table, "stiffness_N_per_m", where, positive=True)
        factor = read_number(p, table, "rest_length_factor", where, default=1.0, positive=True)
        diagonals = table.get("diagonals", True)
        if not isinstance(diagonals, bool):
            p.add(key_path(where, "diagonals"), f"expected true or false, found "
                  f"{describe(diagonals)}")
            diagonals = None
        grid = table.get("grid")
        grid_where = key_path(where, "grid")
        refs = None
        if grid is not None:
            if not (isinstance(grid, list) and len(grid) >= 2
                    and all(isinstance(row, list) for row in grid)
                    and len({len(row) for row in grid}) == 1 and len(grid[0]) >= 2):
                p.add(grid_where, "expected two or more rows of node names, every row the same "
                      f"length (two or more), found {describe(grid)}")
            else:
                refs = [[_node(p, v, key_path(key_path(grid_where, i), j), ctx, spec)
                         for j, v in enumerate(row)] for i, row in enumerate(grid)]
                flat = [r for row in refs for r in row]
                if any(r is None for r in flat):
                    refs = None
                elif len(set(flat)) != len(flat):
                    twice = sorted({r for r in flat if flat.count(r) > 1})
                    p.add(grid_where, f"expected each node once in the grid, found {twice} "
                          "more than once")
                    refs = None
        if None in (name, stiffness, factor, diagonals) or refs is None:
            continue
        rows, cols = len(refs), len(refs[0])
        pairs = [((i, j), (i, j + 1)) for i in range(rows) for j in range(cols - 1)]
        pairs += [((i, j), (i + 1, j)) for i in range(rows - 1) for j in range(cols)]
        if diagonals:
            pairs += [((i, j), (i + 1, j + 1)) for i in range(rows - 1) for j in range(cols - 1)]
            pairs += [((i, j + 1), (i + 1, j)) for i in range(rows - 1)
                      for j in range(cols - 1)]
        for a, b in pairs:
            ref_a, ref_b = refs[a[0]][a[1]], refs[b[0]][b[1]]
            x_a = _reference_position(ref_a, ctx, spec)
            x_b = _reference_position(ref_b, ctx, spec)
            length = float(np.linalg.norm(x_a - x_b))
            if length <= 0.0:
                p.add(grid_where, f"nodes {ref_a!r} and {ref_b!r} coincide: a canopy line "
                      "needs a positive length")
                continue
            spec.lines.append(Line(ref_a, ref_b, float(stiffness), factor * length,
                                   name=f"canopy {name} ({a[0]},{a[1]})-({b[0]},{b[1]})"))


def _read_point_masses(p, value, ctx, spec: ElementSpec):
    tables = read_table(p, value, "point_mass", array=True)
    if tables is None:
        return
    for index, table in enumerate(tables):
        where = key_path("point_mass", index)
        check_keys(p, table, where, ("node", "mass_kg"),
                   {"node": "a node name", "mass_kg": "a positive mass [kg]"})
        ref = _node(p, table["node"], key_path(where, "node"), ctx, spec) \
            if "node" in table else None
        mass = read_number(p, table, "mass_kg", where, positive=True)
        if ref is None or mass is None:
            continue
        if ref in spec.point_positions and any(
                isinstance(pt, FixedPoint) and pt.name == ref for pt in spec.points):
            p.add(key_path(where, "node"), f"expected a node that moves, found the fixed point "
                  f"{ref!r} (its reaction would carry the mass)")
            continue
        spec.point_masses.append(PointMass(ref, float(mass)))


_READERS = {"point": _read_points, "line": _read_lines, "pulley": _read_pulleys,
            "canopy": _read_canopies, "point_mass": _read_point_masses}


def read_element_tables(p, document: dict, ctx) -> ElementSpec:
    """Read the element tables of a parsed spec (after the tubes), recording problems in
    ``p``; returns what they hold."""
    spec = ElementSpec()
    for key in ELEMENT_TABLES:
        if key in document:
            _READERS[key](p, document[key], ctx, spec)
    return spec
