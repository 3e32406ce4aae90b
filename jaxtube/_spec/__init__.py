"""Structure specs in TOML: loading and validation.

A spec file describes one structure and one load path. :func:`load_spec` reads it, checks
every key and value, and returns ``(structure, params, path, metadata)``: a
:class:`~jaxtube.Structure`, its :class:`~jaxtube.StructureParameters`, a
:class:`~jaxtube.DisplacementControl` or :class:`~jaxtube.ForceControl`, and a
:class:`SpecMetadata` with what the CLI needs for reporting. Every problem raises
:class:`SpecError` (a ``ValueError``) naming the file, the key path (e.g.
``cantilever.toml: tube[0].bending_law.curvature_per_m``), what was expected and what was
found; all problems found in one pass are reported together, one per line.

The key reference (format version 1) is ``docs/spec-format.md``. Tables: ``[[tube]]``,
``[[support]]``, ``[[connection]]``, ``[[load]]``, ``[gravity]``, ``[path]``, ``[kite]``;
reserved for a later version: ``[[canopy]]``, ``[[line]]``, ``[[point_mass]]``.

Modules: :mod:`.check` (value checkers, :class:`SpecError`), :mod:`.context` (what the
readers gather, node names), :mod:`.laws`, :mod:`.tubes`, :mod:`.tables` (supports,
connections, loads, gravity, path), :mod:`.kite` (the ``[kite]`` table), :mod:`.load` (the
entry points, in the order the tables are read).
"""

from .check import SpecError as SpecError
from .load import LoadedSpec as LoadedSpec
from .load import SpecMetadata as SpecMetadata
from .load import load_spec as load_spec
from .load import parse_spec as parse_spec
from .load import spec_from_dict as spec_from_dict
from .tables import DEFAULT_STEPS as DEFAULT_STEPS
from .tables import FORMAT_VERSION as FORMAT_VERSION
