"""kite_fem's tube beams as jaxtube tubes: chains of beams, radii per node, junctions.

kite_fem describes a kite's inflated frame as separate two-node beams (``beam_matrix``:
node 1, node 2, diameter, pressure, rest length). jaxtube's tubes are chains of rigid
segments, so the beams are grouped into chains:

- **A chain is a run of consecutive rows of ``beam_matrix`` in which each beam starts at the
  node where the previous one ends** (kite_fem writes each tube that way: the V3 model's
  ten chordwise chains of six beams, then the 28 leading-edge beams along the odd wing
  nodes 1, 3, ..., 57). A beam whose start is not the previous beam's end begins a new
  chain. A chain that would visit a node twice, or whose beams change pressure, is split
  there (a tube has one pressure; a loop is not a chain).
- **Radius per node** (jaxtube evaluates its joint laws at nodes): half the mean diameter of
  the chain's beams that meet at the node (the two neighbours inside a chain, the one beam
  at a chain's end).
- **Junctions**: a node shared by two chains is one physical node; the later chain is
  rigidly connected to the first chain that has the node (``Connection(..., "rigid")``: a
  strut clamped into the leading edge, a wing-tip chain into the leading edge's end).

The rest length of a kite_fem beam is its reference length in the V3 file (checked by the
importer): jaxtube's segments are rigid, so a beam whose rest length differs from its nodes'
distance cannot be represented and is an error.

**Spring groups** (:func:`spring_groups`): canopy springs and bridle lines are the same
tension-only lines; they are told apart only to draw and report them.

This module is pure NumPy (no solver).
"""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class BeamChain:
    """One chain of kite_fem beams that becomes one jaxtube tube.

    Attributes:
        nodes: kite_fem node indices along the chain, ``n_beams + 1`` of them.
        beam_rows: the rows of ``beam_matrix``, in chain order.
        radius: ``[n_beams + 1]`` tube radius at each node [m].
        pressure_bar: the chain's overpressure in the file [bar].
    """

    nodes: tuple[int, ...]
    beam_rows: tuple[int, ...]
    radius: np.ndarray
    pressure_bar: float

    @property
    def name(self) -> str:
        """``"beams_<first node>_<last node>"`` (kite_fem numbering)."""
        return f"beams_{self.nodes[0]}_{self.nodes[-1]}"


def beam_chains(beam_nodes, beam_diameter, beam_pressure_bar) -> list[BeamChain]:
    """Group beams ``[B, 2]`` into chains (module docstring), in the order of the file.

    Every beam belongs to exactly one chain, with its direction as in the file.
    """
    beam_nodes = np.asarray(beam_nodes, dtype=np.int64)
    diameter = np.asarray(beam_diameter, dtype=float)
    pressure = np.asarray(beam_pressure_bar, dtype=float)
    runs: list[list[int]] = []
    for row, (start, _) in enumerate(beam_nodes):
        current = runs[-1] if runs else None
        continues = (
            current is not None
            and beam_nodes[current[-1], 1] == start
            and pressure[current[-1]] == pressure[row]
            and int(beam_nodes[row, 1]) not in {int(beam_nodes[current[0], 0])}
            | {int(beam_nodes[r, 1]) for r in current}
        )
        if continues:
            current.append(row)
        else:
            runs.append([row])
    chains = []
    for rows in runs:
        nodes = (int(beam_nodes[rows[0], 0]),) + tuple(int(beam_nodes[r, 1]) for r in rows)
        d = diameter[rows]
        node_diameter = np.empty(len(nodes))
        node_diameter[0], node_diameter[-1] = d[0], d[-1]
        node_diameter[1:-1] = 0.5 * (d[:-1] + d[1:])
        chains.append(BeamChain(nodes=nodes, beam_rows=tuple(rows), radius=0.5 * node_diameter,
                                pressure_bar=float(pressure[rows[0]])))
    return chains


def chain_junctions(chains: list[BeamChain]) -> list[tuple[tuple[str, int], tuple[str, int]]]:
    """Rigid junctions ``((tube, index), (tube, index))``: each node shared by chains is
    joined from the first chain (in file order) that has it to every later one."""
    first_seen: dict[int, tuple[str, int]] = {}
    junctions = []
    for chain in chains:
        for index, node in enumerate(chain.nodes):
            if node in first_seen:
                junctions.append((first_seen[node], (chain.name, index)))
            else:
                first_seen[node] = (chain.name, index)
    return junctions


def spring_groups(spring_nodes, beam_nodes) -> tuple[str, ...]:
    """``"canopy"`` or ``"bridle"`` per spring: a spring is a canopy spring when each of its
    ends is a tube node or a corner of a triangle of springs (the canopy is a mesh with
    diagonals; bridle lines form trees of lines and pulleys, without triangles). Used to
    draw and report the two apart; the physics of both is the same tension-only line."""
    spring_nodes = np.asarray(spring_nodes, dtype=np.int64)
    neighbours: dict[int, set[int]] = {}
    for a, b in spring_nodes.tolist():
        neighbours.setdefault(a, set()).add(b)
        neighbours.setdefault(b, set()).add(a)
    mesh = set(np.asarray(beam_nodes, dtype=np.int64).ravel().tolist())
    for a, b in spring_nodes.tolist():
        if neighbours[a] & neighbours[b]:
            mesh.update((a, b))
    return tuple("canopy" if a in mesh and b in mesh else "bridle"
                 for a, b in spring_nodes.tolist())
