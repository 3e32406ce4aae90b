"""Reader of kite_fem model files (``initial.npz``): the file format, apart from physics.

kite_fem (awegroup/kite_fem, MIT, (c) 2025 Patrick Roeleveld) stores an assembled kite as
NumPy arrays in an ``.npz`` archive. The keys read here (the rest is that solver's internal
state and is ignored):

- ``initial_conditions_array`` ``[N, 8]``: x, y, z [m], three velocity components (unused),
  nodal mass [kg], fixed flag (0 or 1).
- ``beam_matrix`` ``[B, 5]``: node 1, node 2, tube diameter [m], pressure [bar], rest
  length [m].
- ``spring_matrix`` ``[S, 6]`` (strings): node 1, node 2, stiffness [N/m], damping
  (unused), rest length [m], kind (``noncompressive``: tension only; ``default``: a spring
  that also pushes).
- ``pulley_matrix`` ``[P, 6]``: node 1, pulley node, node 3, stiffness [N/m], damping
  (unused), rest length [m] of the whole rope over the pulley.

This module imports nothing of the solver: it only checks the file and returns NumPy arrays.
Every problem raises :class:`KiteFemFormatError` naming the file, the key, the row and the
column, and what was expected.
"""

from __future__ import annotations

import dataclasses
import zipfile
from pathlib import Path

import numpy as np

SPRING_KINDS = ("noncompressive", "default")
"""Spring kinds of kite_fem: ``noncompressive`` carries tension only; ``default`` is a
linear spring in tension and compression."""

_NODE_COLUMNS = 8
_BEAM_COLUMNS = ("node 1", "node 2", "diameter [m]", "pressure [bar]", "rest length [m]")
_SPRING_COLUMNS = ("node 1", "node 2", "stiffness [N/m]", "damping", "rest length [m]", "kind")
_PULLEY_COLUMNS = ("node 1", "pulley node", "node 3", "stiffness [N/m]", "damping",
                   "rest length [m]")


class KiteFemFormatError(ValueError):
    """A kite_fem file that cannot be read: the message names file, key, row and column."""


@dataclasses.dataclass(frozen=True, eq=False)
class KiteFemModel:
    """A kite_fem model as read from its file (numbers as in the file; SI units).

    Attributes:
        path: the file read.
        node_position: ``[N, 3]`` node positions [m] in kite_fem's frame.
        node_mass: ``[N]`` lumped nodal masses [kg].
        node_fixed: ``[N]`` bool, kite_fem's fixed flag.
        beam_nodes: ``[B, 2]`` int node indices of each tube beam.
        beam_diameter: ``[B]`` tube diameter [m].
        beam_pressure_bar: ``[B]`` inflation overpressure [bar].
        beam_rest_length: ``[B]`` [m].
        spring_nodes: ``[S, 2]`` int node indices of each spring (canopy springs and bridle
            lines).
        spring_stiffness: ``[S]`` k [N/m].
        spring_rest_length: ``[S]`` [m].
        spring_kind: ``S`` strings, one of :data:`SPRING_KINDS`.
        pulley_nodes: ``[P, 3]`` int (node 1, pulley node, node 3).
        pulley_stiffness: ``[P]`` k of the rope [N/m].
        pulley_rest_length: ``[P]`` rest length of the whole rope [m].

    Arrays are read-only copies.
    """

    path: Path
    node_position: np.ndarray
    node_mass: np.ndarray
    node_fixed: np.ndarray
    beam_nodes: np.ndarray
    beam_diameter: np.ndarray
    beam_pressure_bar: np.ndarray
    beam_rest_length: np.ndarray
    spring_nodes: np.ndarray
    spring_stiffness: np.ndarray
    spring_rest_length: np.ndarray
    spring_kind: tuple[str, ...]
    pulley_nodes: np.ndarray
    pulley_stiffness: np.ndarray
    pulley_rest_length: np.ndarray

    def __post_init__(self):
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if isinstance(value, np.ndarray):
                value.setflags(write=False)

    @property
    def node_count(self) -> int:
        return self.node_position.shape[0]

    @property
    def total_mass(self) -> float:
        """Sum of the nodal masses [kg]."""
        return float(self.node_mass.sum())

    def element_free_nodes(self) -> np.ndarray:
        """Indices of the nodes that belong to no beam, spring or pulley (sorted)."""
        used = np.zeros(self.node_count, bool)
        for nodes in (self.beam_nodes, self.spring_nodes, self.pulley_nodes):
            used[nodes.ravel()] = True
        return np.flatnonzero(~used)


def _fail(path, key, message) -> KiteFemFormatError:
    return KiteFemFormatError(f"{path}: key {key!r}: {message}")


def _matrix(archive, path, key, columns: int, numeric: bool) -> np.ndarray:
    if key not in archive.files:
        raise _fail(path, key, f"missing (the file has: {', '.join(sorted(archive.files))})")
    try:
        array = archive[key]
    except ValueError as err:  # object arrays need pickle, which is never enabled
        raise _fail(path, key, f"cannot be read without pickle ({err})") from None
    if array.ndim != 2 or array.shape[1] != columns:
        raise _fail(path, key, f"expected shape [rows, {columns}], found {list(array.shape)}")
    if numeric and not np.issubdtype(array.dtype, np.number):
        raise _fail(path, key, f"expected numbers, found dtype {array.dtype}")
    return array


def _numbers(path, key, array, column: int, name: str) -> np.ndarray:
    """Column ``column`` as float64; strings are parsed, each failure named by row."""
    out = np.empty(array.shape[0])
    for row, value in enumerate(array[:, column]):
        try:
            out[row] = float(value)
        except (TypeError, ValueError):
            raise _fail(path, key, f"row {row}, column {column} ({name}): expected a number, "
                                   f"found {value!r}") from None
        if not np.isfinite(out[row]):
            raise _fail(path, key, f"row {row}, column {column} ({name}): expected a finite "
                                   f"number, found {value!r}")
    return out


def _node_indices(path, key, array, columns, names, node_count) -> np.ndarray:
    out = np.empty((array.shape[0], len(columns)), dtype=np.int64)
    for j, column in enumerate(columns):
        values = _numbers(path, key, array, column, names[column])
        for row, value in enumerate(values):
            if value != np.round(value):
                raise _fail(path, key, f"row {row}, column {column} ({names[column]}): "
                                       f"expected a node index, found {value!r}")
            if not 0 <= value < node_count:
                raise _fail(path, key, f"row {row}, column {column} ({names[column]}): node "
                                       f"{int(value)} out of range (the model has nodes "
                                       f"0..{node_count - 1})")
        out[:, j] = values.astype(np.int64)
    return out


def _positive(path, key, values, column: int, name: str, allow_zero=False) -> np.ndarray:
    bad = np.flatnonzero(values < 0 if allow_zero else values <= 0)
    if bad.size:
        row = int(bad[0])
        expected = "a non-negative" if allow_zero else "a positive"
        raise _fail(path, key, f"row {row}, column {column} ({name}): expected {expected} "
                               f"number, found {values[row]!r}"
                    + (f" ({bad.size} rows in all)" if bad.size > 1 else ""))
    return values


def _distinct(path, key, nodes: np.ndarray) -> None:
    for row, row_nodes in enumerate(nodes):
        if len(set(row_nodes.tolist())) != len(row_nodes):
            raise _fail(path, key, f"row {row}: an element joins node {int(row_nodes[0])} "
                                   f"to itself (nodes {row_nodes.tolist()})")


def read_kite_fem(path) -> KiteFemModel:
    """Read a kite_fem model (``initial.npz``) into a :class:`KiteFemModel`.

    Checks every key this package uses: presence, shape, numbers, node indices in range,
    positive diameter, pressure, stiffness and rest lengths, non-negative masses, known
    spring kinds. Raises :class:`KiteFemFormatError` (a ``ValueError``) naming the file, key,
    row and column; ``FileNotFoundError`` if there is no file.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such kite_fem model file")
    try:
        archive = np.load(path, allow_pickle=False)
    except (ValueError, OSError, zipfile.BadZipFile) as err:
        raise KiteFemFormatError(f"{path}: not a NumPy .npz archive ({err})") from None
    with archive:
        key = "initial_conditions_array"
        nodes = _matrix(archive, path, key, _NODE_COLUMNS, numeric=True).astype(float)
        if nodes.shape[0] == 0:
            raise _fail(path, key, "expected at least one node, found 0 rows")
        for column, name in ((0, "x [m]"), (1, "y [m]"), (2, "z [m]"), (6, "mass [kg]"),
                             (7, "fixed flag")):
            _numbers(path, key, nodes, column, name)
        mass = _positive(path, key, nodes[:, 6], 6, "mass [kg]", allow_zero=True)
        flags = nodes[:, 7]
        bad = np.flatnonzero((flags != 0) & (flags != 1))
        if bad.size:
            raise _fail(path, key, f"row {int(bad[0])}, column 7 (fixed flag): expected 0 or 1, "
                                   f"found {flags[bad[0]]!r}")
        node_count = nodes.shape[0]

        key = "beam_matrix"
        beams = _matrix(archive, path, key, len(_BEAM_COLUMNS), numeric=True)
        beam_nodes = _node_indices(path, key, beams, (0, 1), _BEAM_COLUMNS, node_count)
        _distinct(path, key, beam_nodes)
        diameter = _positive(path, key, _numbers(path, key, beams, 2, _BEAM_COLUMNS[2]), 2,
                             _BEAM_COLUMNS[2])
        pressure = _positive(path, key, _numbers(path, key, beams, 3, _BEAM_COLUMNS[3]), 3,
                             _BEAM_COLUMNS[3])
        beam_length = _positive(path, key, _numbers(path, key, beams, 4, _BEAM_COLUMNS[4]), 4,
                                _BEAM_COLUMNS[4])

        key = "spring_matrix"
        springs = _matrix(archive, path, key, len(_SPRING_COLUMNS), numeric=False)
        spring_nodes = _node_indices(path, key, springs, (0, 1), _SPRING_COLUMNS, node_count)
        _distinct(path, key, spring_nodes)
        stiffness = _positive(path, key, _numbers(path, key, springs, 2, _SPRING_COLUMNS[2]),
                              2, _SPRING_COLUMNS[2])
        spring_length = _positive(
            path, key, _numbers(path, key, springs, 4, _SPRING_COLUMNS[4]), 4,
            _SPRING_COLUMNS[4])
        kinds = tuple(str(k).strip() for k in springs[:, 5])
        for row, kind in enumerate(kinds):
            if kind not in SPRING_KINDS:
                raise _fail(path, key, f"row {row}, column 5 (kind): unknown spring kind "
                                       f"{kind!r}; expected one of {', '.join(SPRING_KINDS)}")

        key = "pulley_matrix"
        if key in archive.files:
            pulleys = _matrix(archive, path, key, len(_PULLEY_COLUMNS), numeric=False)
        else:  # a kite without pulleys may leave the key out
            pulleys = np.zeros((0, len(_PULLEY_COLUMNS)))
        pulley_nodes = _node_indices(path, key, pulleys, (0, 1, 2), _PULLEY_COLUMNS,
                                     node_count)
        _distinct(path, key, pulley_nodes)
        pulley_k = _positive(path, key, _numbers(path, key, pulleys, 3, _PULLEY_COLUMNS[3]), 3,
                             _PULLEY_COLUMNS[3])
        pulley_length = _positive(
            path, key, _numbers(path, key, pulleys, 5, _PULLEY_COLUMNS[5]), 5,
            _PULLEY_COLUMNS[5])

    return KiteFemModel(
        path=path,
        node_position=np.ascontiguousarray(nodes[:, :3]),
        node_mass=mass.copy(),
        node_fixed=flags == 1,
        beam_nodes=beam_nodes,
        beam_diameter=diameter,
        beam_pressure_bar=pressure,
        beam_rest_length=beam_length,
        spring_nodes=spring_nodes,
        spring_stiffness=stiffness,
        spring_rest_length=spring_length,
        spring_kind=kinds,
        pulley_nodes=pulley_nodes,
        pulley_stiffness=pulley_k,
        pulley_rest_length=pulley_length,
    )


def read_kite_fem_positions(path, node_count: int | None = None) -> np.ndarray:
    """Node positions ``[N, 3]`` [m] of a kite_fem solved state (``coords_current``, the
    positions flattened node by node, as in ``states/load_case_*.npz``)."""
    path = Path(path)
    key = "coords_current"
    with np.load(path, allow_pickle=False) as archive:
        if key not in archive.files:
            raise _fail(path, key, "missing")
        flat = np.asarray(archive[key], dtype=float)
    if flat.ndim != 1 or flat.size % 3:
        raise _fail(path, key, f"expected a flat array of 3 N numbers, found shape "
                               f"{list(flat.shape)}")
    positions = flat.reshape(-1, 3)
    if node_count is not None and positions.shape[0] != node_count:
        raise _fail(path, key, f"expected {node_count} nodes, found {positions.shape[0]}")
    return positions
