"""Import a kite_fem model into jaxtube, keeping kite_fem's node numbering, and hang it.

:func:`import_kite_fem` turns a :class:`~jaxtube._io.kite_fem_reader.KiteFemModel` (or the
path of an ``initial.npz``) into a jaxtube structure and its parameters:

- **Tubes.** Chains of beams become tubes (``kite_fem_tubes``: the rows of ``beam_matrix``
  that follow each other end to start), with a radius per node from the beams' diameters
  and one pressure; a node shared by two chains is a rigid ``Connection`` (struts clamped
  into the leading edge). Bending and torsion laws are the caller's: Breukels' 2011
  empirical laws by default (as kite_fem and Billow use), the bending one optionally scaled
  (``ScaledLaw``: the peers needed 0.23-0.36 on the V3 kite).
- **Point nodes.** Every other node that an element uses is a free point node (three
  translations) named ``"node_<i>"``; the suspension nodes are fixed points.
- **Lines.** Each spring (canopy springs and bridle lines: tension only, ``k (l - L0)``) is a
  ``Line``, each pulley a ``Pulley`` with the rope's rest length; compression springs
  (kite_fem's ``default`` kind) are refused, jaxtube has none.
- **Masses.** Every non-zero nodal mass is a point mass under ``params.gravity`` (kite_fem's
  lumped masses include the tubes', so the tubes get no mass per length). The masses on a
  tube's nodes carry its weight and its translational and bending inertia; its spin about
  its own axis gets ``params.inertia.spin_mass_per_length``, per tube the mass on its nodes
  over its length (a node shared by two tubes counts for the first), which adds no mass.
- **Held nodes.** Nodes that belong to no element (kite_fem keeps a few: in the V3 model 0,
  72, 81, 106, 115, 127, 128, 129) take no part in the solve; they stay where they are and are
  reported there.
- **Case loads** of the V3 hanging test: a mass hanging at ``centre_node`` (its weight along
  ``gravity``) and horizontal pulls of ``tip_load_kg * |g|`` N apart along +y / -y at
  ``tip_nodes`` (the README of ``experiments/data/v3_hanging``).

The result (:class:`KiteFemImport`) maps every kite_fem node to its jaxtube node, so that
:meth:`KiteFemImport.kite_positions` gives ``[N, 3]`` positions in kite_fem numbering and
frame. :func:`hang_kite` solves the hung kite from the undeformed shape, stepping gravity
and loads up in ``steps`` increments inside one ``jit``.
"""

from __future__ import annotations

import csv
import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._elements import FixedPoint, Line, PointMass, PointNode, Pulley
from .._equilibrium import Solution, constraint_count, equilibrium
from .._laws import (
    AbstractMomentLaw,
    EmpiricalBendingLaw2011,
    EmpiricalTorsionLaw2011,
    ScaledLaw,
)
from .._mechanics import initial_state
from .._solver import NewtonKKT
from .._structure import (
    Connection,
    Structure,
    StructureParameters,
    Support,
    Tube,
    build_structure,
)
from .kite_fem_reader import KiteFemModel, read_kite_fem
from .kite_fem_tubes import beam_chains, chain_junctions, spring_groups

PASCAL_PER_BAR = 1e5
STANDARD_GRAVITY = 9.81  # m/s^2, as kite_fem
V3_SUSPENSION = (82, 116)
V3_CENTRE_NODE = 29
V3_TIP_NODES = (2, 58)


@dataclasses.dataclass(frozen=True, eq=False)
class KiteFemImport:
    """A kite_fem model as a jaxtube structure, with kite_fem's node numbering kept.

    Attributes:
        structure, params: the jaxtube structure and its parameters.
        model: the kite_fem model read.
        node_index: ``[N]`` int, the jaxtube global node of each kite_fem node (tube nodes
            first, then point nodes, as ``Solution.node_position``), ``-1`` for a held node
            (one that belongs to no element).
        held_nodes: kite_fem indices of the held nodes.
        suspension: kite_fem indices of the fixed suspension nodes.
        tube_names: one tube per beam chain (``"beams_<first>_<last>"``, kite_fem nodes).
        spring_group: per spring row (= per line, same order): ``"canopy"`` or ``"bridle"``
            (see :func:`spring_groups`; for reports and figures only).
    """

    structure: Structure
    params: StructureParameters
    model: KiteFemModel
    node_index: np.ndarray
    held_nodes: tuple[int, ...]
    suspension: tuple[int, ...]
    tube_names: tuple[str, ...]
    spring_group: tuple[str, ...]

    def kite_positions(self, node_position) -> np.ndarray:
        """``[N, 3]`` positions [m] in kite_fem numbering from jaxtube's ``node_position``
        ``[..., N_jaxtube, 3]`` (a leading step axis is kept); held nodes where they are."""
        node_position = np.asarray(node_position, dtype=float)
        lead = node_position.shape[:-2]
        out = np.broadcast_to(self.model.node_position,
                              lead + self.model.node_position.shape).copy()
        mapped = self.node_index >= 0
        out[..., mapped, :] = node_position[..., self.node_index[mapped], :]
        return out


def tube_spin_mass(chains, tube_ref: dict, model: KiteFemModel, held) -> np.ndarray:
    """Per tube ``[T]`` [kg/m]: the point masses on its nodes (a node shared by two tubes
    counts for the first, as ``tube_ref`` says) over its length; the spin-only mass per
    length of :class:`jaxtube.InertiaParameters`."""
    position = model.node_position
    spin = []
    for chain in chains:
        nodes = [n for n in chain.nodes if n not in held and tube_ref[n][0] == chain.name]
        length = np.linalg.norm(np.diff(position[list(chain.nodes)], axis=0), axis=1).sum()
        spin.append(float(np.sum(model.node_mass[nodes])) / length)
    return np.asarray(spin)


def import_kite_fem(
    model,
    pressure_bar=None,
    bending_law: AbstractMomentLaw | None = None,
    torsion_law: AbstractMomentLaw | None = None,
    bending_scale: float | None = None,
    suspension=V3_SUSPENSION,
    gravity=(0.0, 0.0, STANDARD_GRAVITY),
    centre_load_kg: float = 0.0,
    centre_node: int = V3_CENTRE_NODE,
    tip_load_kg: float = 0.0,
    tip_nodes=V3_TIP_NODES,
    tension_smoothing: float | None = None,
    length_tolerance: float = 1e-6,
) -> KiteFemImport:
    """Build a jaxtube structure from a kite_fem model (module docstring).

    Args:
        model: a :class:`KiteFemModel` or the path of a kite_fem ``initial.npz``.
        pressure_bar: tube overpressure [bar] for every tube; ``None`` keeps the file's.
        bending_law: the tubes' bending law; default Breukels' 2011 empirical law
            (``EmpiricalBendingLaw2011``).
        torsion_law: the tubes' torsion law; default ``EmpiricalTorsionLaw2011``.
        bending_scale: if given, the bending law becomes ``ScaledLaw(law, bending_scale)``.
        suspension: kite_fem nodes held fixed in space (the V3 test: 82 and 116).
        gravity: gravitational acceleration ``[3]`` [m/s^2] (kite_fem's frame: +z).
        centre_load_kg: mass hanging at ``centre_node`` [kg] (V3 cases 2, 3: 9.7, 25.2).
        tip_load_kg: weight [kg] pulling ``tip_nodes[0]`` along +y and ``tip_nodes[1]`` along
            -y, with ``|gravity|`` (V3 cases 4, 5: 2, 5).
        tension_smoothing: strain width of the lines' slack-taut blend (``None``: jaxtube's
            default).
        length_tolerance: relative mismatch allowed between a beam's rest length and its
            nodes' distance (jaxtube's segments are rigid at their reference length).

    Raises ``ValueError`` for a beam whose rest length is not its length, a compression
    spring, or a suspension/load node that does not exist.
    """
    if not isinstance(model, KiteFemModel):
        model = read_kite_fem(model)
    where = str(model.path)
    n_nodes = model.node_count
    for name, nodes in (("suspension", suspension), ("tip_nodes", tip_nodes),
                        ("centre_node", (centre_node,))):
        for node in nodes:
            if not 0 <= int(node) < n_nodes:
                raise ValueError(f"{where}: {name} node {node} does not exist (nodes "
                                 f"0..{n_nodes - 1})")
    if len(tuple(tip_nodes)) != 2:
        raise ValueError(f"tip_nodes: expected two nodes, got {tip_nodes!r}")
    position = model.node_position
    length = np.linalg.norm(position[model.beam_nodes[:, 0]] - position[model.beam_nodes[:, 1]],
                            axis=1)
    mismatch = np.abs(model.beam_rest_length - length) / length
    if np.any(mismatch > length_tolerance):
        row = int(np.argmax(mismatch))
        raise ValueError(
            f"{where}: key 'beam_matrix': row {row}, column 4 (rest length [m]): "
            f"{model.beam_rest_length[row]:.6g} m but its nodes are {length[row]:.6g} m apart; "
            "jaxtube's tube segments are rigid at their reference length")
    compressive = [row for row, kind in enumerate(model.spring_kind) if kind != "noncompressive"]
    if compressive:
        raise ValueError(f"{where}: key 'spring_matrix': row {compressive[0]}, column 5 (kind): "
                         f"{model.spring_kind[compressive[0]]!r} springs also push; jaxtube's "
                         "lines carry tension only (expected 'noncompressive')")

    bending = EmpiricalBendingLaw2011() if bending_law is None else bending_law
    if bending_scale is not None:
        bending = ScaledLaw(bending, bending_scale)
    torsion = EmpiricalTorsionLaw2011() if torsion_law is None else torsion_law

    chains = beam_chains(model.beam_nodes, model.beam_diameter, model.beam_pressure_bar)
    tubes = []
    tube_ref: dict[int, tuple[str, int]] = {}
    for chain in chains:
        pressure = chain.pressure_bar if pressure_bar is None else float(pressure_bar)
        if not pressure > 0.0:
            raise ValueError(f"pressure_bar: expected a positive number, got {pressure_bar!r}")
        tubes.append(Tube(chain.name, position[list(chain.nodes)], chain.radius,
                          pressure * PASCAL_PER_BAR, bending, torsion))
        for index, node in enumerate(chain.nodes):
            tube_ref.setdefault(node, (chain.name, index))
    connections = [Connection(a, b, "rigid") for a, b in chain_junctions(chains)]

    held = tuple(int(n) for n in model.element_free_nodes() if int(n) not in set(suspension))
    suspension = tuple(int(n) for n in suspension)
    gravity = np.asarray(gravity, dtype=float)
    g = float(np.linalg.norm(gravity))
    load = np.zeros((n_nodes, 3))
    load[centre_node] += centre_load_kg * gravity
    load[tip_nodes[0], 1] += tip_load_kg * g
    load[tip_nodes[1], 1] -= tip_load_kg * g

    def ref(node: int):
        return tube_ref.get(node, f"node_{node}")

    supports, points, masses = [], [], []
    node_force = {}
    for node in range(n_nodes):
        if node in held:
            continue
        mass = float(model.node_mass[node])
        if node in tube_ref:
            if node in suspension:
                supports.append(Support(tube_ref[node], "pinned"))
            if mass > 0.0:
                masses.append(PointMass(tube_ref[node], mass))
            if np.any(load[node]):
                node_force[tube_ref[node]] = load[node]
        elif node in suspension:
            points.append(FixedPoint(f"node_{node}", position[node]))
            if mass > 0.0:
                masses.append(PointMass(f"node_{node}", mass))
        else:
            points.append(PointNode(f"node_{node}", position[node], mass=mass, force=load[node]))
    groups = spring_groups(model.spring_nodes, model.beam_nodes)
    lines = [Line(ref(int(a)), ref(int(b)), float(k), float(rest),
                  name=f"{group} {row} ({a}-{b})")
             for row, ((a, b), k, rest, group) in enumerate(zip(
                 model.spring_nodes, model.spring_stiffness, model.spring_rest_length, groups))]
    pulleys = [Pulley(ref(int(a)), ref(int(p)), ref(int(b)), float(k), float(rest),
                      name=f"pulley {row} ({a}-{p}-{b})")
               for row, ((a, p, b), k, rest) in enumerate(zip(
                   model.pulley_nodes, model.pulley_stiffness, model.pulley_rest_length))]
    extra = {} if tension_smoothing is None else {"tension_smoothing": float(tension_smoothing)}
    structure, params = build_structure(
        tubes, supports, connections, node_force=node_force or None, gravity=gravity,
        points=points, lines=lines, pulleys=pulleys, point_masses=masses, **extra)

    params = eqx.tree_at(lambda p: p.inertia.spin_mass_per_length, params,
                         jnp.asarray(tube_spin_mass(chains, tube_ref, model, held)))

    node_index = np.full(n_nodes, -1, dtype=np.int64)
    for node in range(n_nodes):
        if node not in held:
            node_index[node] = structure.node_id(ref(node))
    return KiteFemImport(structure=structure, params=params, model=model,
                         node_index=node_index, held_nodes=held, suspension=suspension,
                         tube_names=tuple(t.name for t in tubes), spring_group=groups)


class HangStart(eqx.Module):
    """Where a hang starts: a state PyTree and the constraint multipliers ``[m]``."""

    state: dict
    multipliers: jax.Array


def undeformed_start(structure: Structure, params: StructureParameters) -> HangStart:
    """The undeformed shape with zero multipliers."""
    return HangStart(initial_state(structure, params),
                     jnp.zeros((constraint_count(structure),)))


def restart_from(solution: Solution) -> HangStart:
    """Start again from the last step of a hang (more Newton steps without recompiling)."""
    return HangStart(jax.tree_util.tree_map(lambda x: x[-1], solution.state),
                     solution.multipliers[-1])


def scale_gravity_and_loads(params: StructureParameters, factor) -> StructureParameters:
    """Parameters with gravity and every dead point force times ``factor``."""
    elements = params.elements
    return eqx.tree_at(
        lambda p: (p.gravity, p.node_force, p.elements.point_force), params,
        (factor * params.gravity, factor * params.node_force, factor * elements.point_force))


def hang_kite(structure: Structure, params: StructureParameters, steps: int = 1,
              solver: NewtonKKT = NewtonKKT(), start: HangStart | None = None,
              load_factors=None, tension_smoothing=None) -> Solution:
    """Hang a structure: gravity and point loads are stepped up to full in ``steps`` equal
    increments (``lax.scan`` over one traced solve, each step warm-started from the
    previous), from ``start`` (default: the undeformed shape, :func:`undeformed_start`).
    Returns the :class:`Solution` of every step (leading axis ``[steps]``; ``load_factor``
    is the step's fraction of gravity and loads), each with its own convergence report.
    Traceable: ``jax.jit(partial(hang_kite, structure))``; see :func:`hang_until_converged`.

    A continuation instead of equal increments: ``load_factors`` ``[K]`` (fractions of
    gravity and loads, one per step; ``steps`` is then ignored) and ``tension_smoothing``
    ``[K]`` (the lines' blend width per step, ``params.elements.tension_smoothing`` by
    default). Wide blends first let Newton cross the slack-taut changes of many lines in
    few steps; the last step, at the model's own width, is the equilibrium reported (every
    step is a converged equilibrium of its own parameters, or says it is not).
    """
    if load_factors is None:
        factors = jnp.arange(1, steps + 1, dtype=float) / steps
    else:
        factors = jnp.asarray(load_factors, dtype=float).reshape(-1)
    if tension_smoothing is None:
        widths = jnp.broadcast_to(params.elements.tension_smoothing, factors.shape)
    else:
        widths = jnp.asarray(tension_smoothing, dtype=float).reshape(-1)
        if widths.shape != factors.shape:
            raise ValueError(f"tension_smoothing: expected {factors.shape[0]} widths (one per "
                             f"step), got {widths.shape[0]}")
    if start is None:
        start = undeformed_start(structure, params)

    def step(carry, factor_and_width):
        factor, width = factor_and_width
        stepped = eqx.tree_at(lambda p: p.elements.tension_smoothing,
                              scale_gravity_and_loads(params, factor), width)
        sol = equilibrium(structure, stepped, initial=carry, solver=solver)
        sol = eqx.tree_at(lambda s: s.load_factor, sol, factor)
        return HangStart(sol.state, sol.multipliers), sol

    _, solutions = jax.lax.scan(step, start, (factors, widths))
    return solutions


def hang_program(structure: Structure, steps: int = 1, solver: NewtonKKT = NewtonKKT(),
                 load_factors=None, tension_smoothing=None):
    """``(params, start) -> Solution``: :func:`hang_kite` of ``structure`` with the start
    as a traced argument (jit it once; :func:`hang_until_converged` restarts it)."""

    def run(params, start):
        return hang_kite(structure, params, steps, solver, start, load_factors,
                         tension_smoothing)

    return run


def hang_until_converged(structure: Structure, params: StructureParameters, steps: int = 1,
                         solver: NewtonKKT = NewtonKKT(), restarts: int = 8, compiled=None):
    """Host loop around :func:`hang_kite`: while the last step has not converged, solve
    again from where the previous run stopped (each run is ``solver.max_steps`` more Newton
    steps; one compiled program). A structure hung from an arbitrary undeformed shape may
    have to swing far and pull slack lines taut, which takes Newton many steps.

    Returns ``(solution, runs)``: the last run's :class:`Solution` (its convergence flags
    are the truth: a run that never converged is reported so) and the number of runs.
    ``compiled``: a ``(params, start) -> Solution`` function to reuse (default: jitted
    here).
    """
    if compiled is None:
        compiled = jax.jit(hang_program(structure, steps, solver))
    solution = compiled(params, undeformed_start(structure, params))
    runs = 1
    while runs <= restarts and not bool(np.asarray(solution.converged)[-1]):
        solution = compiled(params, restart_from(solution))
        runs += 1
    return solution, runs


def write_positions_csv(path, positions) -> None:
    """``node,x_m,y_m,z_m``: one row per node ``[N, 3]`` [m], in kite_fem numbering."""
    positions = np.asarray(positions, dtype=float)
    with open(path, "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["node", "x_m", "y_m", "z_m"])
        for node, (x, y, z) in enumerate(positions):
            writer.writerow([node, repr(float(x)), repr(float(y)), repr(float(z))])
