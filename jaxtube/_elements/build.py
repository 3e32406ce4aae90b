"""Compile point nodes, fixed points, lines, pulleys and masses against a tube structure.

Called by ``build_structure``; resolves node references, creates one attachment point per
tube node that an element uses, checks every number, and returns the static
:class:`ElementTopology` with its :class:`ElementParameters`.
"""

from __future__ import annotations

from collections.abc import Sequence

import jax.numpy as jnp
import numpy as np

from .lines import Line, Pulley
from .points import (
    DEFAULT_TENSION_SMOOTHING,
    ElementParameters,
    ElementTopology,
    FixedPoint,
    PointMass,
    PointNode,
)


def _vector3(value, what: str) -> np.ndarray:
    try:
        vec = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: expected 3 numbers, got {value!r}") from None
    if vec.shape != (3,) or not np.all(np.isfinite(vec)):
        raise ValueError(f"{what}: expected 3 finite numbers, got {value!r}")
    return vec


def _positive(value, what: str, unit: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: expected a number [{unit}], got {value!r}") from None
    if not np.isfinite(number) or number <= 0.0:
        raise ValueError(f"{what}: expected a positive number [{unit}], got {value!r}")
    return number


def build_elements(
    structure,
    tube_position: np.ndarray,
    points: Sequence[PointNode | FixedPoint] = (),
    lines: Sequence[Line] = (),
    pulleys: Sequence[Pulley] = (),
    point_masses: Sequence[PointMass] = (),
    merge_tolerance: float = 1e-9,
    tension_smoothing: float = DEFAULT_TENSION_SMOOTHING,
) -> tuple[ElementTopology, ElementParameters, dict[int, np.ndarray]]:
    """Resolve and check the elements of a structure.

    Args:
        structure: the tube :class:`Structure` (its ``node_id`` resolves tube references).
        tube_position: reference tube node positions ``[N, 3]`` [m].

    Returns ``(topology, parameters, alias_forces)``: ``alias_forces`` maps tube nodes to
    the dead forces [N] of point nodes joined to them (to be added to ``node_force``).
    Raises ``ValueError`` naming the element and what was expected.
    """
    node_count = int(structure.node_count)
    tube_position = np.asarray(tube_position, dtype=float).reshape(-1, 3)
    scale = max(1.0, float(np.abs(tube_position).max(initial=0.0)))
    own_names: list[str] = []
    own_position: list[np.ndarray] = []
    own_force: list[np.ndarray] = []
    fixed_rows: list[int] = []
    aliases: list[tuple[str, int]] = []
    alias_forces: dict[int, np.ndarray] = {}
    masses: list[tuple[object, float, str]] = []
    seen: set[str] = set()
    for k, point in enumerate(points):
        what = f"point {k} ({getattr(point, 'name', '?')!r})"
        if not isinstance(point, PointNode | FixedPoint):
            raise ValueError(f"{what}: expected a PointNode or FixedPoint, got {point!r}")
        name = str(point.name)
        if not name or ":" in name:
            raise ValueError(f"{what}: a point name must be non-empty and contain no ':' "
                             "(that marks a tube node reference)")
        if name in seen:
            raise ValueError(f"{what}: duplicate point name {name!r}")
        seen.add(name)
        if isinstance(point, FixedPoint):
            fixed_rows.append(len(own_names))
            own_names.append(name)
            own_position.append(_vector3(point.position, f"{what}: position [m]"))
            own_force.append(np.zeros(3))
            continue
        mass = float(point.mass)
        if not np.isfinite(mass) or mass < 0.0:
            raise ValueError(f"{what}: mass must be a non-negative number [kg], got {mass!r}")
        force = _vector3(point.force, f"{what}: force [N]")
        joined = None
        if point.at is not None:
            joined = structure.node_id(point.at)
        else:
            position = _vector3(point.position, f"{what}: position [m]")
            if len(tube_position):
                gap = np.linalg.norm(tube_position - position, axis=1)
                nearest = int(np.argmin(gap))
                if gap[nearest] <= merge_tolerance * scale:
                    joined = nearest
        if joined is not None:
            aliases.append((name, joined))
            alias_forces[joined] = alias_forces.get(joined, np.zeros(3)) + force
            if mass > 0.0:
                masses.append((joined, mass, what))
            continue
        if mass > 0.0:
            masses.append((node_count + len(own_names), mass, what))
        own_names.append(name)
        own_position.append(position)
        own_force.append(force)

    topology = ElementTopology(point_names=tuple(own_names), aliases=tuple(aliases))
    attachments: list[int] = []

    def resolve(ref, what: str) -> int:
        """Global node index of a reference (point name, 'tube:index' or an integer)."""
        if isinstance(ref, int | np.integer):
            index = int(ref)
            if not 0 <= index < node_count + len(own_names):
                raise ValueError(f"{what}: node {index} does not exist (nodes 0.."
                                 f"{node_count + len(own_names) - 1})")
            return index
        if isinstance(ref, str) and ":" not in ref:
            found = topology.point_id(ref.strip(), node_count)
            if found is None:
                raise ValueError(f"{what}: no point named {ref!r} (points: "
                                 f"{', '.join(own_names + [a for a, _ in aliases]) or 'none'})")
            return found
        try:
            return structure.node_id(ref)
        except ValueError as err:
            raise ValueError(f"{what}: {err}") from None

    def row_of(node: int) -> int:
        """Row of ``state["point_position"]`` for a global node (attachment on demand)."""
        if node >= node_count:
            return node - node_count
        if node not in attachments:
            attachments.append(node)
        return len(own_names) + attachments.index(node)

    reference = np.concatenate([tube_position, np.asarray(own_position).reshape(-1, 3)])

    line_ends, line_names, line_k, line_l0 = [], [], [], []
    for k, line in enumerate(lines):
        what = f"line {k}" + (f" ({line.name!r})" if line.name else "")
        if not isinstance(line, Line):
            raise ValueError(f"{what}: expected a Line, got {line!r}")
        a, b = resolve(line.end_a, f"{what}: end_a"), resolve(line.end_b, f"{what}: end_b")
        if a == b:
            raise ValueError(f"{what}: both ends are node {a}")
        length = float(np.linalg.norm(reference[a] - reference[b]))
        rest = (length if line.rest_length is None
                else _positive(line.rest_length, f"{what}: rest_length", "m"))
        if rest <= 0.0:
            raise ValueError(f"{what}: its ends coincide, give a positive rest_length [m]")
        line_k.append(_positive(line.stiffness, f"{what}: stiffness", "N/m"))
        line_l0.append(rest)
        line_ends.append((row_of(a), row_of(b)))
        line_names.append(line.name or f"line {k}")

    pulley_ends, pulley_names, pulley_k, pulley_l0 = [], [], [], []
    for k, pulley in enumerate(pulleys):
        what = f"pulley {k}" + (f" ({pulley.name!r})" if pulley.name else "")
        if not isinstance(pulley, Pulley):
            raise ValueError(f"{what}: expected a Pulley, got {pulley!r}")
        a = resolve(pulley.end_a, f"{what}: end_a")
        p = resolve(pulley.pulley, f"{what}: pulley")
        b = resolve(pulley.end_b, f"{what}: end_b")
        if p in (a, b):
            raise ValueError(f"{what}: the pulley node {p} is also a rope end")
        length = float(np.linalg.norm(reference[a] - reference[p])
                       + np.linalg.norm(reference[b] - reference[p]))
        rest = (length if pulley.rest_length is None
                else _positive(pulley.rest_length, f"{what}: rest_length", "m"))
        pulley_k.append(_positive(pulley.stiffness, f"{what}: stiffness", "N/m"))
        pulley_l0.append(rest)
        pulley_ends.append((row_of(a), row_of(p), row_of(b)))
        pulley_names.append(pulley.name or f"pulley {k}")

    mass_rows, mass_values = [], []
    for node, mass, what in masses:
        mass_rows.append(row_of(node))
        mass_values.append(mass)
    for k, item in enumerate(point_masses):
        what = f"point mass {k}"
        if not isinstance(item, PointMass):
            raise ValueError(f"{what}: expected a PointMass, got {item!r}")
        mass = float(item.mass)
        if not np.isfinite(mass) or mass < 0.0:
            raise ValueError(f"{what}: mass must be a non-negative number [kg], got {item.mass!r}")
        mass_rows.append(row_of(resolve(item.node, f"{what}: node")))
        mass_values.append(mass)

    _positive(tension_smoothing, "tension_smoothing (strain)", "-")
    used = {row for ends in line_ends + pulley_ends for row in ends}
    loose = [own_names[k] for k in range(len(own_names))
             if k not in fixed_rows and k not in used]
    if loose:
        raise ValueError(f"point nodes {loose} belong to no line or pulley: nothing holds "
                         "them (make them FixedPoints or connect them)")
    topology = ElementTopology(
        point_names=tuple(own_names),
        aliases=tuple(aliases),
        fixed_points=tuple(fixed_rows),
        attachment_nodes=tuple(attachments),
        line_ends=tuple(line_ends),
        line_names=tuple(line_names),
        pulley_ends=tuple(pulley_ends),
        pulley_names=tuple(pulley_names),
        mass_points=tuple(mass_rows),
    )
    parameters = ElementParameters(
        point_position=jnp.asarray(np.asarray(own_position).reshape(-1, 3)),
        point_force=jnp.asarray(np.asarray(own_force).reshape(-1, 3)),
        point_mass=jnp.asarray(np.asarray(mass_values, dtype=float)),
        line_stiffness=jnp.asarray(np.asarray(line_k, dtype=float)),
        line_rest_length=jnp.asarray(np.asarray(line_l0, dtype=float)),
        pulley_stiffness=jnp.asarray(np.asarray(pulley_k, dtype=float)),
        pulley_rest_length=jnp.asarray(np.asarray(pulley_l0, dtype=float)),
        tension_smoothing=jnp.asarray(float(tension_smoothing)),
    )
    return topology, parameters, alias_forces
