"""Point nodes, fixed points and lumped masses: descriptions, static topology, parameters.

A *point node* has three translations and no rotation. Its position is an unknown of the
state, ``state["point_position"]`` ``[P, 3]`` [m]; it carries lumped masses (under
``StructureParameters.gravity``) and dead point forces, and lines and pulleys join it to
other nodes. A *fixed point* is a point node held at its reference position by an equality
constraint, whose multiplier is minus the reaction force (reported per fixed point).

Tube nodes join the same machinery through *attachment points*: every tube node that a
line, pulley or point mass refers to gets one point unknown tied to it by the equality
constraint ``p - x_node = 0``. Line energies then depend only on point positions (small
6 x 6 and 9 x 9 Hessian blocks), and the tie is linear both in ``p`` and in the tube's
segment vectors, so it adds nothing to the tube part of the Hessian beyond the per-segment
terms the tube assembly already has. The tie's multiplier is the force the tube node
takes from its lines and masses. A :class:`PointNode` declared ``at`` a tube node, or whose
position coincides with one, is an alias of that tube node (joined to it).
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax.numpy as jnp
from jax import Array

DEFAULT_TENSION_SMOOTHING = 1e-4  # strain width of the slack-taut blend (see lines.py)


@dataclasses.dataclass(frozen=True)
class PointNode:
    """A free point node (three translations).

    Attributes:
        name: unique name (no ``":"``), used by lines, pulleys, masses and ``node_id``.
        position: reference position ``[3]`` [m] (the initial guess of the solve); may be
            ``None`` when ``at`` is given.
        mass: lumped mass [kg] under gravity.
        force: dead point force ``[3]`` [N] (scaled by :class:`ForceControl`).
        at: ``"tube:index"`` to declare the point an alias of that tube node. A point whose
            position coincides with a tube node (``build_structure``'s ``merge_tolerance``)
            is joined to it the same way.
    """

    name: str
    position: object = None
    mass: float = 0.0
    force: object = (0.0, 0.0, 0.0)
    at: object = None


@dataclasses.dataclass(frozen=True)
class FixedPoint:
    """A point held in space at ``position`` [m] ``[3]``; its reaction force [N] is
    reported in ``Solution.fixed_point_reaction``."""

    name: str
    position: object


@dataclasses.dataclass(frozen=True)
class PointMass:
    """A lumped mass [kg] at a node (point name, ``"tube:index"`` or global index), under
    ``StructureParameters.gravity``."""

    node: object
    mass: float


class ElementTopology(eqx.Module):
    """Static topology of point nodes, lines, pulleys and masses (hashable).

    Point unknowns (rows of ``state["point_position"]``): the structure's own point nodes
    first (free and fixed, in declaration order; global node id ``node_count + k``), then
    one attachment point per tube node that an element refers to.
    """

    point_names: tuple[str, ...] = eqx.field(static=True, default=())
    aliases: tuple[tuple[str, int], ...] = eqx.field(static=True, default=())  # name, tube node
    fixed_points: tuple[int, ...] = eqx.field(static=True, default=())  # rows that are held
    attachment_nodes: tuple[int, ...] = eqx.field(static=True, default=())  # tube node per row
    line_ends: tuple[tuple[int, int], ...] = eqx.field(static=True, default=())  # point rows
    line_names: tuple[str, ...] = eqx.field(static=True, default=())
    pulley_ends: tuple[tuple[int, int, int], ...] = eqx.field(static=True, default=())
    pulley_names: tuple[str, ...] = eqx.field(static=True, default=())
    mass_points: tuple[int, ...] = eqx.field(static=True, default=())  # point row per mass

    @property
    def own_point_count(self) -> int:
        """Point nodes of the structure itself (not attachment points)."""
        return len(self.point_names)

    @property
    def unknown_count(self) -> int:
        """Rows of ``state["point_position"]``."""
        return len(self.point_names) + len(self.attachment_nodes)

    @property
    def constraint_count(self) -> int:
        """Equality constraints: 3 per fixed point, then 3 per attachment tie."""
        return 3 * (len(self.fixed_points) + len(self.attachment_nodes))

    @property
    def active(self) -> bool:
        return self.unknown_count > 0

    def point_id(self, name: str, node_count: int) -> int | None:
        """Global node index of a point name, or ``None``."""
        if name in self.point_names:
            return node_count + self.point_names.index(name)
        for alias, node in self.aliases:
            if alias == name:
                return node
        return None


class ElementParameters(eqx.Module):
    """Every number of the point nodes, lines, pulleys and masses (a PyTree).

    Attributes:
        point_position: reference positions of the structure's point nodes ``[P0, 3]`` [m]
            (fixed points are held there).
        point_force: dead forces on them ``[P0, 3]`` [N].
        point_mass: lumped masses ``[M]`` [kg] at ``ElementTopology.mass_points``.
        line_stiffness, line_rest_length: ``[L]`` [N/m], [m].
        pulley_stiffness, pulley_rest_length: ``[Q]`` [N/m], [m] (whole rope).
        tension_smoothing: strain width ``delta`` of the slack-taut blend (scalar; tension
            error at most ``k L0 delta / 8``, see ``jaxtube._elements.lines``).
    """

    point_position: Array = eqx.field(default_factory=lambda: jnp.zeros((0, 3)))
    point_force: Array = eqx.field(default_factory=lambda: jnp.zeros((0, 3)))
    point_mass: Array = eqx.field(default_factory=lambda: jnp.zeros((0,)))
    line_stiffness: Array = eqx.field(default_factory=lambda: jnp.zeros((0,)))
    line_rest_length: Array = eqx.field(default_factory=lambda: jnp.zeros((0,)))
    pulley_stiffness: Array = eqx.field(default_factory=lambda: jnp.zeros((0,)))
    pulley_rest_length: Array = eqx.field(default_factory=lambda: jnp.zeros((0,)))
    tension_smoothing: Array = eqx.field(
        default_factory=lambda: jnp.asarray(DEFAULT_TENSION_SMOOTHING))
