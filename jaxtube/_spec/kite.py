"""The ``[kite]`` table of a TOML spec: a tube kite from :class:`~jaxtube.TubeKite`.

Keys (reference; the spec format as a whole is documented in docs/spec-format.md)::

    [kite]
    tip_support = "clamped"            # or "pinned": both wing tips

    [kite.leading_edge]                # the tube "le"
    segments = 24                      # even: le:centre is a node
    pressure_bar = 0.25                # or pressure_kPa / pressure_Pa
    span_m = 2.4                       # circular arc through the tips and the crown, or
    arc_height_m = 0.9                 #   points_m = [[x, y, z], ...] (left tip first)
    centre_radius_m = 0.08             # double taper, linear from the centre to the tips,
    tip_radius_m = 0.04                #   or radius_m (a number or [[fraction, r], ...])
    mass_per_length_kg_per_m = 0.0     # optional
    line_load_N_per_m = [0, 0, 0]      # optional
    [kite.leading_edge.bending_law]    # required; same kinds as [tube.bending_law]
    [kite.leading_edge.torsion_law]    # optional

    [[kite.strut]]                     # optional, several: strut_1, strut_2, ...
    span_fraction = 0.25               # along the leading edge from the left tip, in (0, 1)
    chord_m = 0.7
    segments = 8
    root_radius_m = 0.05               # linear taper from root to tip,
    tip_radius_m = 0.025               #   or radius_m
    pressure_bar = 0.3                 # optional: default the leading edge's
    direction = [1, 0, 0]              # optional: chordwise direction
    mass_per_length_kg_per_m, line_load_N_per_m     # optional
    [kite.strut.bending_law]           # optional: default the leading edge's law
    [kite.strut.torsion_law]           # optional

The kite adds the tubes ``le`` and ``strut_k``, their rigid connections and the two tip
supports; ``[[tube]]``, ``[[support]]`` and ``[[connection]]`` tables may add more. Node
names: ``le:centre``, ``le:left_tip``, ``le:right_tip``, ``strut_k:root``, ``strut_k:end``,
and every ``tube:index``.
"""

from __future__ import annotations

from .._structure.kite import LEADING_EDGE, Strut, TubeKite, double_taper
from .check import (
    array_tables,
    check_keys,
    describe,
    key_path,
    read_number,
    read_pressure,
    read_string,
    read_table,
    read_vector,
    read_vector_key,
)
from .context import read_node
from .laws import read_law
from .tubes import read_radius

_GEOMETRY_KEYS = ("span_m", "arc_height_m", "points_m")
_LE_KEYS = ("segments", "pressure_bar", "pressure_kPa", "pressure_Pa", "centre_radius_m",
            "tip_radius_m", "radius_m", "mass_per_length_kg_per_m", "line_load_N_per_m",
            "bending_law", "torsion_law") + _GEOMETRY_KEYS
_STRUT_KEYS = ("span_fraction", "chord_m", "segments", "root_radius_m", "tip_radius_m",
               "radius_m", "pressure_bar", "pressure_kPa", "pressure_Pa", "direction",
               "mass_per_length_kg_per_m", "line_load_N_per_m", "bending_law", "torsion_law")


def _taper_radius(p, table, where, inner: str, outer: str, make):
    """``radius_m``, or the pair ``inner``/``outer`` (positive) turned into a taper by
    ``make(inner, outer)``; exactly one form."""
    pair = [k for k in (inner, outer) if k in table]
    if "radius_m" in table and pair:
        p.add(key_path(where, pair[0]), f"cannot be combined with radius_m (give either "
              f"radius_m or {inner} and {outer})")
        return None
    if "radius_m" in table:
        return read_radius(p, table, where)
    if len(pair) < 2:
        missing = inner if inner not in table else outer
        p.add(key_path(where, missing), f"missing required key (expected {inner} and {outer} "
              f"[m], or radius_m)")
        return None
    a = read_number(p, table, inner, where, positive=True)
    b = read_number(p, table, outer, where, positive=True)
    return None if a is None or b is None else make(float(a), float(b))


def _largest(radius):
    return radius if isinstance(radius, float) else max(r for _, r in radius)


def _common(p, table, where):
    mass = read_number(p, table, "mass_per_length_kg_per_m", where, default=0.0, minimum=0.0)
    line_load = read_vector_key(p, table, "line_load_N_per_m", where, default=(0, 0, 0))
    return mass, line_load


def _laws(p, table, where, pressure, radius, required):
    if "bending_law" not in table:
        if required:
            p.add(key_path(where, "bending_law"), "missing required table (expected a "
                  "[kite.leading_edge.bending_law] table, same kinds as [tube.bending_law])")
        bending = None
    else:
        bending = read_law(p, table["bending_law"], key_path(where, "bending_law"),
                           "bending", pressure, None if radius is None else _largest(radius))
    torsion = (read_law(p, table["torsion_law"], key_path(where, "torsion_law"), "torsion",
                        pressure, None if radius is None else _largest(radius))
               if "torsion_law" in table else None)
    return bending, torsion


def _leading_edge(p, value, where):
    table = read_table(p, value, where)
    if table is None:
        return None
    count = len(p)
    check_keys(p, table, where, _LE_KEYS, {"segments": "an even positive integer"})
    segments = read_number(p, table, "segments", where, positive=True, integer=True)
    if segments is not None and segments % 2:
        p.add(key_path(where, "segments"), f"expected an even number of segments (so that "
              f"le:centre is a node), found {segments}")
    pressure = read_pressure(p, table, where, "pressure")
    radius = _taper_radius(p, table, where, "centre_radius_m", "tip_radius_m", double_taper)
    mass, line_load = _common(p, table, where)
    geometry = {}
    if "points_m" in table:
        for key in ("span_m", "arc_height_m"):
            if key in table:
                p.add(key_path(where, key), "cannot be combined with points_m (give span_m and "
                      "arc_height_m for a circular arc, or points_m for a sampled centreline)")
        points = table["points_m"]
        if not isinstance(points, list) or len(points) < 2:
            p.add(key_path(where, "points_m"), f"expected a list of two or more points "
                  f"[[x, y, z], ...], found {describe(points)}")
        else:
            rows = [read_vector(p, point, key_path(key_path(where, "points_m"), i))
                    for i, point in enumerate(points)]
            geometry = dict(centreline=tuple(map(tuple, rows))) if all(
                r is not None for r in rows) else {}
    else:
        for key in ("span_m", "arc_height_m"):
            if key not in table:
                p.add(key_path(where, key), "missing required key (expected span_m and "
                      "arc_height_m [m], positive, or points_m)")
        geometry = dict(span=read_number(p, table, "span_m", where, positive=True),
                        arc_height=read_number(p, table, "arc_height_m", where, positive=True))
    bending, torsion = _laws(p, table, where, pressure, radius, required=True)
    if len(p) > count:
        return None
    return dict(segments=segments, radius=radius, pressure=pressure, bending_law=bending,
                torsion_law=torsion, mass_per_length=float(mass),
                line_load=tuple(line_load.tolist()), **geometry)


def _strut(p, table, where, le_pressure):
    count = len(p)
    check_keys(p, table, where, _STRUT_KEYS, {
        "span_fraction": "a number in (0, 1)", "chord_m": "a positive length [m]",
        "segments": "a positive integer"})
    fraction = read_number(p, table, "span_fraction", where)
    if fraction is not None and not 0.0 < fraction < 1.0:
        p.add(key_path(where, "span_fraction"), f"expected a fraction of the leading edge's "
              f"length strictly between 0 and 1 (the tips are supports), found {fraction!r}")
    chord = read_number(p, table, "chord_m", where, positive=True)
    segments = read_number(p, table, "segments", where, positive=True, integer=True)
    radius = _taper_radius(p, table, where, "root_radius_m", "tip_radius_m",
                           lambda a, b: ((0.0, a), (1.0, b)))
    own_pressure = any(k.startswith("pressure_") for k in table)
    pressure = read_pressure(p, table, where, "pressure") if own_pressure else None
    direction = read_vector_key(p, table, "direction", where, default=(1, 0, 0), nonzero=True)
    mass, line_load = _common(p, table, where)
    bending, torsion = _laws(p, table, where, pressure if own_pressure else le_pressure,
                             radius, required=False)
    if len(p) > count:
        return None
    return Strut(float(fraction), float(chord), radius, segments, pressure=pressure,
                 bending_law=bending, torsion_law=torsion, mass_per_length=float(mass),
                 line_load=tuple(line_load.tolist()), direction=tuple(direction.tolist()))


def read_kite(p, value, ctx) -> None:
    """Check the ``[kite]`` table and add its tubes, connections, supports and node names
    to the spec context ``ctx`` (:class:`~.context.SpecContext`)."""
    table = read_table(p, value, "kite")
    if table is None:
        return
    count = len(p)
    check_keys(p, table, "kite", ("tip_support", "leading_edge", "strut"),
               {"leading_edge": "a [kite.leading_edge] table"})
    tip_support = read_string(p, table, "tip_support", "kite", default="clamped",
                              choices=("clamped", "pinned"))
    le = (_leading_edge(p, table["leading_edge"], "kite.leading_edge")
          if "leading_edge" in table else None)
    struts = []
    strut_tables = array_tables(p, table["strut"], "kite.strut") if "strut" in table else []
    for where, strut_table in strut_tables:
        struts.append(_strut(p, strut_table, where, None if le is None else le["pressure"]))
    names = [LEADING_EDGE] + [f"strut_{k + 1}" for k in range(len(struts))]
    for name in names:
        if name in ctx.tube_nodes:
            p.add("kite", f"the kite's tube {name!r} clashes with a [[tube]] of that name "
                  "(rename the [[tube]])")
    if len(p) > count or le is None or any(strut is None for strut in struts):
        ctx.tube_names_known = False
        return
    try:
        kite = TubeKite(struts=tuple(struts), tip_support=tip_support, **le)
        tubes = kite.tubes()
    except ValueError as error:
        p.add("kite", f"cannot build the kite: {error}")
        ctx.tube_names_known = False
        return
    ctx.tubes.extend(tubes)
    for tube in tubes:
        ctx.tube_nodes[tube.name] = tube.nodes.shape[0]
    ctx.node_aliases.update(kite.node_aliases())

    def node(ref: str, where: str):
        return read_node(p, ref, where, ctx)

    for support in kite.supports():
        ctx.supports.append(("kite.tip_support", node(support.node, "kite.tip_support"),
                             support.kind))
    for k, connection in enumerate(kite.connections()):
        where = key_path("kite.strut", k)
        ctx.connections.append((where, node(connection.node_a, where),
                                node(connection.node_b, where), connection.kind))
