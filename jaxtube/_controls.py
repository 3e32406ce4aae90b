"""What a load path imposes: load factors (force control) or a driven node (displacement
control).

- :class:`ForceControl`: the point forces, torques and line loads of the parameters are
  scaled by each load factor; self-weight stays on (gravity is not a test load).
- :class:`DisplacementControl`: one node is driven along a unit direction
  (``(x - X) . d = u``); the force the actuator applies along ``d`` is the constraint's
  reaction. This traces softening and the collapse plateau, where force control fails.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
from jax import Array

from ._structure.structure import StructureParameters


class ForceControl(eqx.Module):
    """Load factors ``[K]`` applied to the point forces, torques and line loads."""

    load_factors: Array

    def __init__(self, load_factors):
        self.load_factors = jnp.asarray(load_factors, dtype=float)


class DisplacementControl(eqx.Module):
    """Drive ``node`` (global index: a tube node or a point node) along unit
    ``direction [3]`` by ``displacements [K]`` [m]."""

    node: int = eqx.field(static=True)
    direction: Array
    displacements: Array

    def __init__(self, node: int, direction, displacements):
        self.node = int(node)
        direction = jnp.asarray(direction, dtype=float)
        self.direction = direction / jnp.linalg.norm(direction)
        self.displacements = jnp.asarray(displacements, dtype=float)


def scale_loads(params: StructureParameters, factor) -> StructureParameters:
    """Parameters with point forces (on tube and point nodes), torques and line loads
    multiplied by ``factor``."""
    return eqx.tree_at(
        lambda p: (p.node_force, p.node_torque, p.line_load, p.elements.point_force),
        params,
        (params.node_force * factor, params.node_torque * factor, params.line_load * factor,
         params.elements.point_force * factor),
    )
