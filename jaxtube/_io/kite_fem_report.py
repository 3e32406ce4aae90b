"""Reports of a hung kite_fem model: the state of every line and pulley rope, and the balance
of weight, loads and suspension reactions (used by ``jaxtube simulate --kite-fem`` and the V3
experiments)."""

from __future__ import annotations

import numpy as np

from .._plot_elements import point_row_nodes


def kite_fem_line_table(imported, solution, step: int = -1) -> list[dict]:
    """Rows of ``lines.csv`` (module docstring) at one step of a hang."""
    model = imported.model
    rows = []
    length = np.asarray(solution.line_length)[step]
    tension = np.asarray(solution.line_tension)[step]
    taut = np.asarray(solution.line_taut)[step]
    for k, (a, b) in enumerate(model.spring_nodes):
        rows.append(dict(element=imported.spring_group[k], row=k, nodes=f"{a}-{b}",
                         rest_length_m=float(model.spring_rest_length[k]),
                         length_m=float(length[k]), tension_N=float(tension[k]),
                         state="taut" if taut[k] else "slack"))
    rope = np.asarray(solution.pulley_length)[step]
    rope_tension = np.asarray(solution.pulley_tension)[step]
    rope_taut = np.asarray(solution.pulley_taut)[step]
    for k, (a, p, b) in enumerate(model.pulley_nodes):
        rows.append(dict(element="pulley", row=k, nodes=f"{a}-{p}-{b}",
                         rest_length_m=float(model.pulley_rest_length[k]),
                         length_m=float(rope[k]), tension_N=float(rope_tension[k]),
                         state="taut" if rope_taut[k] else "slack"))
    return rows


def weight_and_reactions(imported, solution, step: int = -1) -> dict:
    """Total weight and applied loads [N] (at the step's ``load_factor``), the fixed points'
    reactions [N] and the moment balance about the origin [N m] at one step of
    :func:`hang_kite` (all in kite_fem's frame)."""
    params = imported.params
    structure = imported.structure
    rows = point_row_nodes(structure.elements, structure.node_count)
    position = np.asarray(solution.node_position)[step]
    mass_nodes = rows[np.asarray(structure.elements.mass_points, dtype=int)]
    factor = float(np.atleast_1d(np.asarray(solution.load_factor))[step])
    mass = np.asarray(params.elements.point_mass, dtype=float)
    gravity = factor * np.asarray(params.gravity, dtype=float)
    weight = mass[:, None] * gravity[None, :]
    loads = [(mass_nodes, weight)]
    tube_force = factor * np.asarray(params.node_force, dtype=float)
    loads.append((np.arange(tube_force.shape[0]), tube_force))
    own = factor * np.asarray(params.elements.point_force, dtype=float)
    loads.append((structure.node_count + np.arange(own.shape[0]), own))
    applied = sum(f.sum(axis=0) for _, f in loads)
    moment = sum(np.cross(position[n], f).sum(axis=0) for n, f in loads)
    fixed = structure.node_count + np.asarray(structure.elements.fixed_points, dtype=int)
    reaction = np.asarray(solution.fixed_point_reaction)[step].reshape(-1, 3)
    reaction_moment = np.cross(position[fixed], reaction).sum(axis=0)
    return dict(weight_and_loads_N=applied, reaction_N=reaction,
                reaction_sum_N=reaction.sum(axis=0), applied_moment_Nm=moment,
                reaction_moment_Nm=reaction_moment, total_mass_kg=float(mass.sum()))


def kite_fem_reference_positions(imported) -> np.ndarray:
    """Reference positions of every jaxtube node (tube nodes, then point nodes) [m]."""
    params = imported.params
    return np.concatenate([np.asarray(params.node_position),
                           np.asarray(params.elements.point_position)])
