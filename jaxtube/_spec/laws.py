"""Law tables of a spec: ``[tube.bending_law]``, ``[tube.torsion_law]`` (and the kite's).

Kinds: ``spline`` (from pivots or sampled from the tension-field law), ``tension_field``,
``empirical_2011``, ``linear``; keys in docs/spec-format.md.
"""

from __future__ import annotations

from .._laws import (
    AbstractMomentLaw,
    EmpiricalBendingLaw2011,
    EmpiricalTorsionLaw2011,
    LinearLaw,
    SplineLaw,
    TensionFieldLaw,
)
from .check import (
    check_keys,
    describe,
    key_path,
    read_exponent,
    read_increasing,
    read_number,
    read_pressure,
    read_string,
    read_table,
)

LAW_KINDS = ("spline", "tension_field", "empirical_2011", "linear")
SPLINE_PIVOT_KEYS = ("curvature_per_m", "moment_Nm", "reference_pressure_bar",
                     "reference_pressure_kPa", "reference_pressure_Pa", "reference_radius_m",
                     "curvature_exponent", "moment_exponent", "curvature_radius_exponent",
                     "moment_radius_exponent")
SPLINE_COMMON_KEYS = ("residual_stiffness_ratio", "pivots_per_regime")
SPLINE_TENSION_FIELD_KEY = "from_tension_field_wall_modulus_N_per_m"


def read_law(p, table, where, role, pressure, radius) -> AbstractMomentLaw | None:
    """A law table; ``role`` is "bending" or "torsion"; ``pressure`` [Pa] and the largest
    ``radius`` [m] of the tube (None if invalid) are used by the tension-field spline."""
    table = read_table(p, table, where)
    if table is None:
        return None
    if "kind" not in table:
        p.add(key_path(where, "kind"), f"missing required key (expected one of "
              f"{', '.join(map(repr, LAW_KINDS))})")
        return None
    kind = read_string(p, table, "kind", where, choices=LAW_KINDS)
    if kind is None:
        return None
    count = len(p)
    if kind == "linear":
        check_keys(p, table, where, ("kind", "stiffness_Nm2"),
                   {"stiffness_Nm2": "a positive stiffness [N m^2]"})
        stiffness = read_number(p, table, "stiffness_Nm2", where, positive=True)
        return None if len(p) > count else LinearLaw(float(stiffness))
    if kind == "tension_field":
        check_keys(p, table, where, ("kind", "wall_modulus_N_per_m", "residual_stiffness_ratio"),
                   {"wall_modulus_N_per_m": "a positive wall modulus E t [N/m]"})
        modulus = read_number(p, table, "wall_modulus_N_per_m", where, positive=True)
        ratio = read_number(p, table, "residual_stiffness_ratio", where, default=0.0, minimum=0.0)
        return None if len(p) > count else TensionFieldLaw(float(modulus), float(ratio))
    if kind == "empirical_2011":
        check_keys(p, table, where, ("kind",), {})
        if len(p) > count:
            return None
        return EmpiricalBendingLaw2011() if role == "bending" else EmpiricalTorsionLaw2011()
    return _read_spline(p, table, where, pressure, radius)


def _read_spline(p, table, where, pressure, radius):
    count = len(p)
    from_tension_field = SPLINE_TENSION_FIELD_KEY in table
    if from_tension_field:
        allowed = ("kind", SPLINE_TENSION_FIELD_KEY) + SPLINE_COMMON_KEYS
        for key in table:
            if key in SPLINE_PIVOT_KEYS:
                p.add(key_path(where, key), f"cannot be combined with {SPLINE_TENSION_FIELD_KEY} "
                      "(give either the pivots or the tension-field wall modulus)")
        check_keys(p, {k: v for k, v in table.items() if k not in SPLINE_PIVOT_KEYS}, where,
                   allowed, {})
    else:
        allowed = ("kind",) + SPLINE_PIVOT_KEYS + SPLINE_COMMON_KEYS
        check_keys(p, table, where, allowed + (SPLINE_TENSION_FIELD_KEY,), {
            "curvature_per_m": f"9 increasing pivot curvatures [1/m] (or give "
                               f"{SPLINE_TENSION_FIELD_KEY})",
            "moment_Nm": "9 increasing pivot moments [N m]",
            "reference_radius_m": "the positive radius [m] at which the pivots hold",
        })
    ratio = read_number(p, table, "residual_stiffness_ratio", where, default=0.01, positive=True)
    pivots_per_regime = (3, 3, 3)
    if "pivots_per_regime" in table:
        value = table["pivots_per_regime"]
        if (isinstance(value, list) and len(value) == 3
            and all(isinstance(n, int) and not isinstance(n, bool) and n > 0
                        for n in value)):
            pivots_per_regime = tuple(value)
        else:
            p.add(key_path(where, "pivots_per_regime"), f"expected a list of three positive "
                  f"integers, found {describe(value)}")
            return None
    pivot_count = sum(pivots_per_regime)
    try:
        if from_tension_field:
            modulus = read_number(p, table, SPLINE_TENSION_FIELD_KEY, where, positive=True)
            if len(p) > count or pressure is None or radius is None:
                return None
            return SplineLaw.from_tension_field(
                float(modulus), pressure, radius, residual_stiffness_ratio=float(ratio),
                pivots_per_regime=pivots_per_regime)
        what = f"sum of pivots_per_regime = {list(pivots_per_regime)}"
        curvatures = moments = None
        if "curvature_per_m" in table:
            curvatures = read_increasing(p, table["curvature_per_m"],
                                         key_path(where, "curvature_per_m"), pivot_count, what)
        if "moment_Nm" in table:
            moments = read_increasing(p, table["moment_Nm"], key_path(where, "moment_Nm"),
                                      pivot_count, what)
        reference_pressure = read_pressure(p, table, where, "reference_pressure")
        reference_radius = read_number(p, table, "reference_radius_m", where, positive=True)
        curvature_exponent = read_exponent(p, table, "curvature_exponent", where, pivot_count, 1.0)
        moment_exponent = read_exponent(p, table, "moment_exponent", where, pivot_count, 1.0)
        radius_keys = ("curvature_radius_exponent", "moment_radius_exponent")
        radius_exponents = None
        if any(k in table for k in radius_keys):
            if not all(k in table for k in radius_keys):
                missing = next(k for k in radius_keys if k not in table)
                p.add(key_path(where, missing), "missing key: curvature_radius_exponent and "
                      "moment_radius_exponent go together (give both or neither)")
            else:
                radius_exponents = tuple(read_exponent(p, table, k, where, pivot_count, None)
                                         for k in radius_keys)
        if len(p) > count:
            return None
        return SplineLaw.from_pivots(
            curvatures, moments, reference_pressure, float(reference_radius),
            curvature_exponent=curvature_exponent, moment_exponent=moment_exponent,
            radius_exponents=radius_exponents, residual_stiffness_ratio=float(ratio),
            pivots_per_regime=pivots_per_regime)
    except ValueError as error:
        p.add(where, f"invalid spline law: {error}")
        return None
