"""Loading a spec: the TOML file, every table checked in order, then the structure built.

:func:`load_spec` (a file), :func:`parse_spec` (TOML text) and :func:`spec_from_dict` (a
parsed document) return a :class:`LoadedSpec`; every problem found in one pass is raised
together as a :class:`~jaxtube.SpecError`.
"""

from __future__ import annotations

import dataclasses
import os
import tomllib
from collections.abc import Callable
from typing import Any, NamedTuple

import equinox as eqx
import numpy as np

from .._controls import DisplacementControl, ForceControl
from .._problems import Problem, ProblemReport
from .._structure.build import build_structure
from .._structure.inertia import InertiaParameters, air_density
from .._structure.structure import (
    STANDARD_GRAVITY,
    Connection,
    Structure,
    StructureParameters,
    Support,
)
from .._units import unit_factor
from .check import SpecError, check_keys, format_point, key_path
from .context import SpecContext
from .dynamics import DynamicsSpec, read_dynamics
from .elements import ELEMENT_TABLES, read_element_tables
from .kite import read_kite
from .tables import (
    FORMAT_VERSION,
    read_connections,
    read_gravity,
    read_loads,
    read_path,
    read_scalar,
    read_supports,
)
from .tubes import read_tubes


@dataclasses.dataclass(frozen=True, eq=False)
class SpecMetadata:
    """What a spec says beyond the structure: the path and names, for reporting.

    Attributes:
        source: the spec file as given. name, description: from the spec.
        control: ``"displacement"`` or ``"force"``.
        control_node: global node index of the path node; control_node_ref: its name.
        control_direction: unit vector ``[3]``.
        path_values: ``[K]`` imposed displacements [m] or load factors.
        supports: ``(node_ref, node_id, kind)`` per support.
        loads: ``(node_ref, node_id, force [3] N, torque [3] N m)`` per ``[[load]]``.
        gravity: ``[3]`` [m/s^2]. raw: the parsed TOML document.
        dynamics: the ``[dynamics]`` table (:class:`DynamicsSpec`) or ``None``.
    """

    source: str
    name: str
    description: str
    format_version: int
    control: str
    control_node: int
    control_node_ref: str
    control_direction: np.ndarray
    path_values: np.ndarray
    supports: tuple
    loads: tuple
    gravity: np.ndarray
    raw: dict
    dynamics: DynamicsSpec | None = None

    @property
    def steps(self) -> int:
        return int(self.path_values.shape[0])


class LoadedSpec(NamedTuple):
    """``(structure, params, path, metadata)``, as returned by :func:`load_spec`."""

    structure: Structure
    params: StructureParameters
    path: DisplacementControl | ForceControl
    metadata: SpecMetadata


# Order matters: node names need the tubes (and the kite's); the path checks supports and
# loads.
TABLE_READERS: dict[str, Callable[[ProblemReport, Any, SpecContext], None]] = {
    "format_version": read_scalar("format_version", int),
    "name": read_scalar("name", str),
    "description": read_scalar("description", str),
    "tube": read_tubes,
    "kite": read_kite,
    "support": read_supports,
    "connection": read_connections,
    "load": read_loads,
    "gravity": read_gravity,
    "path": read_path,
    "dynamics": read_dynamics,
}
REQUIRED_TABLES = {"tube": "one or more [[tube]] tables (or a [kite])", "support": "one or "
                   "more [[support]] tables (or a [kite])", "path": "a [path] table"}
# Tables reserved for a later format version get a clear message instead of "unknown key"
# (none today: the whole-kite element tables arrived, jaxtube._spec.elements).
RESERVED_TABLES: dict[str, str] = {}


def load_spec(path: str | os.PathLike, *, steps: int | None = None) -> LoadedSpec:
    """Load and check a TOML spec file; the format is in docs/spec-format.md.

    Arguments:
        path: the ``.toml`` file.
        steps: if given, overrides ``[path].steps``.

    Returns ``(structure, params, path, metadata)`` (a :class:`LoadedSpec`). Raises
    :class:`SpecError` listing every problem found (file, key path, expected, found).
    """
    source = os.fspath(path)
    try:
        with open(source, "rb") as file:
            data = file.read()
    except OSError as error:
        raise SpecError([Problem(source, f"cannot read the spec file: {error.strerror}")]) \
            from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise SpecError([Problem(source, f"not UTF-8 text ({error})")]) from None
    return parse_spec(text, source=source, steps=steps)


def parse_spec(text: str, *, source: str = "<spec>", steps: int | None = None) -> LoadedSpec:
    """Like :func:`load_spec`, from the TOML text; ``source`` names it in messages."""
    try:
        document = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise SpecError([Problem(source, f"TOML syntax error: {error}")]) from None
    return spec_from_dict(document, source=source, steps=steps)


def spec_from_dict(document: dict, *, source: str = "<spec>",
                   steps: int | None = None) -> LoadedSpec:
    """Like :func:`load_spec`, from an already parsed TOML document (a dict)."""
    p = ProblemReport(source)
    required = {k: v for k, v in REQUIRED_TABLES.items()
                if "kite" not in document or k not in ("tube", "support")}
    if "point" in document:  # a fixed point may hold the frame instead (checked below)
        required.pop("support", None)
    for key, what in RESERVED_TABLES.items():
        if key in document:
            p.add(key, f"reserved for {what} in a later spec format version; this jaxtube "
                  f"(format version {FORMAT_VERSION}) cannot simulate it yet")
    check_keys(p, {k: v for k, v in document.items() if k not in RESERVED_TABLES}, "",
               tuple(TABLE_READERS) + ELEMENT_TABLES, required)
    ctx = SpecContext()
    for key, read in TABLE_READERS.items():
        if key in document:
            read(p, document[key], ctx)
    elements = read_element_tables(p, document, ctx)
    if "point" in document and "support" not in document and "kite" not in document \
            and not elements.fixed and not any(  # a bad 'fixed' value is reported already
                isinstance(t, dict) and t.get("fixed", False) is not False
                for t in (document["point"] if isinstance(document["point"], list) else [])):
        p.add("support", "missing required key (expected one or more [[support]] tables, "
              "or a [[point]] with fixed = true holding the structure by lines)")
    if "support" in document and not ctx.supports and isinstance(document["support"], list):
        p.add("support", "expected at least one [[support]]")
    if steps is not None and not (isinstance(steps, int) and steps > 0):
        p.add("path.steps", f"expected a positive integer step count override, found {steps!r}")
    p.raise_if_any(SpecError)

    tubes_by_name = {t.name: t for t in ctx.tubes}
    for where, ref_a, ref_b, _ in ctx.connections:
        a = np.asarray(tubes_by_name[ref_a[0]].nodes[ref_a[1]])
        b = np.asarray(tubes_by_name[ref_b[0]].nodes[ref_b[1]])
        gap = float(np.linalg.norm(a - b))
        if gap > 1e-9 * max(1.0, float(np.abs(a).max())):
            p.add(key_path(where, "nodes"), f"expected coincident nodes, found them {gap:.4g} m "
                  f"apart (at {format_point(a)} and {format_point(b)} m)")
    p.raise_if_any(SpecError)

    def name(ref):
        return f"{ref[0]}:{ref[1]}"

    force: dict[str, np.ndarray] = {}
    torque: dict[str, np.ndarray] = {}
    for _, ref, f, t in ctx.loads:
        force[name(ref)] = force.get(name(ref), 0.0) + f
        torque[name(ref)] = torque.get(name(ref), 0.0) + t
    gravity = ctx.gravity
    if gravity is None:
        has_mass = any(float(t.mass_per_length) > 0 for t in ctx.tubes) or elements.has_mass
        gravity = np.array([0.0, 0.0, -STANDARD_GRAVITY if has_mass else 0.0])
    try:
        structure, params = build_structure(
            ctx.tubes,
            [Support(name(ref), kind) for _, ref, kind in ctx.supports],
            [Connection(name(a), name(b), kind) for _, a, b, kind in ctx.connections],
            node_force=force or None, node_torque=torque or None, gravity=gravity,
            **elements.build_arguments())
    except ValueError as error:
        raise SpecError([Problem(source, f"cannot assemble the structure: {error}")]) \
            from None

    if ctx.dynamics is not None:
        params = with_dynamics_inertia(params, ctx.dynamics)
    path_spec = ctx.path
    count = path_spec["steps"] if steps is None else steps
    fractions = np.arange(1, count + 1) / count
    node_id = structure.node_id(name(path_spec["node"]))
    direction = path_spec["direction"] / np.linalg.norm(path_spec["direction"])
    if path_spec["control"] == "displacement":
        values = fractions * path_spec["maximum"] * unit_factor("length", "mm")
        path = DisplacementControl(node_id, direction, values)
    else:
        values = fractions * path_spec["maximum"]
        path = ForceControl(values)
    metadata = SpecMetadata(
        source=source,
        name=str(document.get("name", "")),
        description=str(document.get("description", "")),
        format_version=int(document.get("format_version", FORMAT_VERSION)),
        control=path_spec["control"],
        control_node=node_id,
        control_node_ref=path_spec["node"].text,
        control_direction=direction,
        path_values=values,
        supports=tuple((ref.text, structure.node_id(name(ref)), kind)
                       for _, ref, kind in ctx.supports),
        loads=tuple((ref.text, structure.node_id(name(ref)), f, t)
                    for _, ref, f, t in ctx.loads),
        gravity=np.asarray(gravity, dtype=float),
        raw=document,
        dynamics=ctx.dynamics,
    )
    return LoadedSpec(structure, params, path, metadata)


def with_dynamics_inertia(params: StructureParameters,
                          dynamics: DynamicsSpec) -> StructureParameters:
    """The inertia a ``[dynamics]`` table asks for: the enclosed air at each tube's
    pressure and ``air_temperature_K`` (ideal gas), and the added mass ``C_a rho_ambient``."""
    enclosed = (air_density(params.pressure, dynamics.air_temperature)
                if dynamics.air_temperature is not None else np.zeros(()))
    inertia = InertiaParameters(
        enclosed_air_density=enclosed,
        added_mass_density=np.asarray(dynamics.added_mass_coefficient
                                      * dynamics.ambient_air_density, float),
        line_mass=params.inertia.line_mass)
    return eqx.tree_at(lambda q: q.inertia, params, inertia)
