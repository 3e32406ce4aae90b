"""Load paths: :func:`solve_path` steps through a :class:`ForceControl` or a
:class:`DisplacementControl` inside ``jit``.

The path is a ``lax.scan`` over steps, each warm-started from the previous one; every step's
solution carries its own convergence flag. Gradients w.r.t. the parameters come by the
implicit function theorem at every step.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ._controls import DisplacementControl, ForceControl, scale_loads
from ._equilibrium import Solution, constraint_count, solve_load_level, tube_reference_geometry
from ._mechanics.kinematics import initial_state
from ._solver.newton_kkt import NewtonKKT
from ._structure.structure import Structure, StructureParameters


def solve_path(
    structure: Structure,
    params: StructureParameters,
    path: ForceControl | DisplacementControl,
    solver: NewtonKKT = NewtonKKT(),
) -> Solution:
    """Follow a load path by stepping (``lax.scan``); returns a :class:`Solution` whose
    leaves have a leading step axis ``[K]``. Each step is warm-started from the previous
    one and reports its own convergence."""
    geometry = tube_reference_geometry(structure, params)
    state0 = initial_state(structure, params)
    m_support = constraint_count(structure)

    if isinstance(path, DisplacementControl):
        lam0 = jnp.zeros((m_support + 1,))

        def step(carry, value):
            state, lam = carry
            ctrl = (path.node, path.direction, value)
            sol = solve_load_level(structure, params, geometry, ctrl, state, lam, solver, 1.0)
            return (sol.state, sol.multipliers), sol

        _, sols = jax.lax.scan(step, (state0, lam0), path.displacements)
        return sols

    lam0 = jnp.zeros((m_support,))

    def step(carry, factor):
        state, lam = carry
        scaled = scale_loads(params, factor)
        sol = solve_load_level(structure, scaled, geometry, None, state, lam, solver, factor)
        return (sol.state, sol.multipliers), sol

    _, sols = jax.lax.scan(step, (state0, lam0), path.load_factors)
    return sols
