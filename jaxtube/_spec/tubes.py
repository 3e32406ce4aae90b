"""``[[tube]]`` tables: name, segments, pressure, radius (or taper), centreline, laws."""

from __future__ import annotations

import math

import numpy as np

from .._structure.tube import arc_tube, polyline_tube, straight_tube
from .check import (
    check_keys,
    describe,
    is_number,
    key_path,
    read_number,
    read_pressure,
    read_string,
    read_table,
    read_vector,
    read_vector_key,
)
from .context import SpecContext
from .laws import read_law

CENTRELINE_KINDS = ("straight", "arc", "polyline")
TUBE_KEYS = ("name", "segments", "pressure_bar", "pressure_kPa", "pressure_Pa", "radius_m",
             "mass_per_length_kg_per_m", "line_load_N_per_m", "centreline", "bending_law",
             "torsion_law")


def read_radius(p, table, where):
    """A positive number or ``[[fraction, radius], ...]`` (fractions increasing in [0, 1])."""
    if "radius_m" not in table:
        return None
    value, key_where = table["radius_m"], key_path(where, "radius_m")
    if is_number(value):
        if math.isfinite(value) and value > 0:
            return float(value)
        p.add(key_where, f"expected a positive radius, found {describe(value)}")
        return None
    pairs_ok = isinstance(value, list) and len(value) >= 1 and all(
        isinstance(pair, list) and len(pair) == 2
        and all(is_number(x) and math.isfinite(x) for x in pair) for pair in value)
    if not pairs_ok:
        p.add(key_where, "expected a positive number or a list of [fraction, radius_m] pairs, "
              f"found {describe(value)}")
        return None
    table_array = np.asarray(value, dtype=float)
    fractions, radii = table_array[:, 0], table_array[:, 1]
    if np.any(fractions < 0) or np.any(fractions > 1) or np.any(np.diff(fractions) <= 0):
        p.add(key_where, "expected fractions of the length in [0, 1], strictly increasing, "
              f"found {fractions.tolist()}")
        return None
    if np.any(radii <= 0):
        p.add(key_where, f"expected positive radii, found {radii.tolist()}")
        return None
    return [tuple(pair) for pair in table_array.tolist()]


def _read_centreline(p, table, where):
    """Returns ``(builder, kwargs)`` with ``builder(name, segments, radius, pressure, law,
    **kwargs)`` making the tube, or None."""
    table = read_table(p, table, where)
    if table is None:
        return None
    if "kind" not in table:
        p.add(key_path(where, "kind"), "missing required key (expected one of "
              f"{', '.join(map(repr, CENTRELINE_KINDS))})")
        return None
    kind = read_string(p, table, "kind", where, choices=CENTRELINE_KINDS)
    count = len(p)
    if kind == "straight":
        check_keys(p, table, where, ("kind", "start_m", "end_m"),
                   {"start_m": "a list of 3 numbers [m]", "end_m": "a list of 3 numbers [m]"})
        start = read_vector_key(p, table, "start_m", where)
        end = read_vector_key(p, table, "end_m", where)
        if start is not None and end is not None and np.array_equal(start, end):
            p.add(key_path(where, "end_m"), f"expected an end different from start_m, found "
                  f"{end.tolist()} for both")
        if len(p) > count:
            return None
        return (lambda name, segments, radius, pressure, law, **kw: straight_tube(
            name, start, end, segments, radius, pressure, law, **kw))
    if kind == "arc":
        check_keys(p, table, where, ("kind", "centre_m", "arc_radius_m", "start_deg",
                                     "end_deg", "normal", "reference"), {
            "centre_m": "a list of 3 numbers [m]", "arc_radius_m": "a positive radius [m]",
            "start_deg": "a number [degrees]", "end_deg": "a number [degrees]"})
        centre = read_vector_key(p, table, "centre_m", where)
        arc_radius = read_number(p, table, "arc_radius_m", where, positive=True)
        start = read_number(p, table, "start_deg", where)
        end = read_number(p, table, "end_deg", where)
        normal = read_vector_key(p, table, "normal", where, default=(0, 0, 1), nonzero=True)
        reference = read_vector_key(p, table, "reference", where, default=(1, 0, 0), nonzero=True)
        if start is not None and end is not None and start == end:
            p.add(key_path(where, "end_deg"), f"expected an angle different from start_deg, found "
                  f"{end!r} for both")
        if normal is not None and reference is not None and np.linalg.norm(
                np.cross(normal, reference)) <= 1e-9 * np.linalg.norm(normal) * np.linalg.norm(
                reference):
            p.add(key_path(where, "reference"), f"expected a vector not parallel to normal "
                  f"{normal.tolist()}, found {reference.tolist()}")
        if len(p) > count:
            return None
        return (lambda name, segments, radius, pressure, law, **kw: arc_tube(
            name, centre, arc_radius, math.radians(start), math.radians(end), segments, radius,
            pressure, law, normal=normal, reference=reference, **kw))
    if kind == "polyline":
        check_keys(p, table, where, ("kind", "points_m"),
                   {"points_m": "a list of two or more points [[x, y, z], ...] [m]"})
        if "points_m" not in table:
            return None
        value, key_where = table["points_m"], key_path(where, "points_m")
        if not isinstance(value, list) or len(value) < 2:
            p.add(key_where, f"expected a list of two or more points [[x, y, z], ...], found "
                  f"{describe(value)}")
            return None
        points = [read_vector(p, point, key_path(key_where, i)) for i, point in enumerate(value)]
        for i in range(1, len(points)):
            if points[i] is not None and points[i - 1] is not None and np.array_equal(
                    points[i], points[i - 1]):
                p.add(key_path(key_where, i), f"expected a point different from the previous one, "
                      f"found {points[i].tolist()} twice")
        if len(p) > count:
            return None
        points = np.stack(points)
        return (lambda name, segments, radius, pressure, law, **kw: polyline_tube(
            name, points, segments, radius, pressure, law, **kw))
    return None


def read_tubes(p, value, ctx: SpecContext):
    tables = read_table(p, value, "tube", array=True)
    if tables is None:
        ctx.tube_names_known = False
        return
    if not tables:
        p.add("tube", "expected at least one [[tube]]")
    for index, table in enumerate(tables):
        where = key_path("tube", index)
        count = len(p)
        check_keys(p, table, where, TUBE_KEYS, {
            "name": "a tube name (string)", "segments": "a positive integer",
            "radius_m": "a positive radius [m] or [[fraction, radius_m], ...]",
            "centreline": "a [tube.centreline] table", "bending_law": "a [tube.bending_law] table"})
        name = read_string(p, table, "name", where)
        if name is not None:
            if not name.strip() or ":" in name:
                p.add(key_path(where, "name"), f"expected a non-empty name without ':', found "
                      f"{name!r}")
                name = None
            elif name in ctx.tube_nodes:
                p.add(key_path(where, "name"), f"expected a unique tube name, found {name!r} again")
                name = None
        segments = read_number(p, table, "segments", where, positive=True, integer=True)
        pressure = read_pressure(p, table, where, "pressure")
        radius = read_radius(p, table, where)
        mass = read_number(p, table, "mass_per_length_kg_per_m", where, default=0.0, minimum=0.0)
        line_load = read_vector_key(p, table, "line_load_N_per_m", where, default=(0, 0, 0))
        builder = (_read_centreline(p, table["centreline"], key_path(where, "centreline"))
                   if "centreline" in table else None)
        largest_radius = None if radius is None else (
            radius if isinstance(radius, float) else max(r for _, r in radius))
        bending = (read_law(p, table["bending_law"], key_path(where, "bending_law"), "bending",
                            pressure, largest_radius) if "bending_law" in table else None)
        torsion = (read_law(p, table["torsion_law"], key_path(where, "torsion_law"), "torsion",
                            pressure, largest_radius) if "torsion_law" in table else None)
        if name is not None:
            ctx.tube_nodes[name] = None if segments is None else segments + 1
        else:
            ctx.tube_names_known = False
        tube = None
        if len(p) == count:
            try:
                tube = builder(name, segments, radius, pressure, bending, torsion_law=torsion,
                               mass_per_length=float(mass), line_load=line_load)
            except ValueError as error:
                p.add(key_path(where, "centreline"), f"cannot build the tube: {error}")
        ctx.tubes.append(tube)
