"""jaxtube: differentiable simulator of inflatable tubular structures.

The rigid-segment method of Breukels & Ockels (2008) on JAX: tubes are chains of rigid
segments joined by spherical joints whose moments follow nonlinear moment-curvature laws;
equilibrium is found by constrained Newton energy minimisation, and differentiated by the
implicit function theorem.

Float64: Newton tolerances need double precision, so importing jaxtube turns on
``jax_enable_x64`` (docs/further/developer.md, "Float64"). Set the environment variable
``JAXTUBE_NO_X64=1`` to keep JAX's default; solves then raise a clear ``TypeError``
instead of silently failing in float32.

Threads: importing jaxtube before JAX has started selects single-threaded XLA CPU kernels
(``--xla_cpu_multi_thread_eigen=false`` in ``XLA_FLAGS``) unless ``XLA_FLAGS`` already sets
that flag or ``JAXTUBE_XLA_THREADS=1`` (docs/further/developer.md, "Threads").

Whole kites (issue 14): point nodes (``PointNode``, ``FixedPoint``), tension-only lines
(``Line``), ropes over pulleys (``Pulley``) and lumped masses (``PointMass``) join tubes in
one energy through ``build_structure(..., points=, lines=, pulleys=, point_masses=)``; the
API summary is the docstring of ``jaxtube._elements``.

Dynamics (issue 37): ``modes`` (natural modes at an equilibrium) and ``simulate_dynamics``
(implicit Newmark on SO(3), each step a Newton-KKT solve); ``docs/dynamics.md``.
"""

from . import _config  # noqa: F401, I001  (first: XLA_FLAGS and float64 before JAX runs)
from ._compilation_cache import enable_compilation_cache as enable_compilation_cache
from ._stored_programs import disable_traced_program_store as disable_traced_program_store
from ._stored_programs import enable_traced_program_store as enable_traced_program_store
from ._stored_programs import stored_jit as stored_jit
from ._controls import DisplacementControl as DisplacementControl
from ._controls import ForceControl as ForceControl
from ._controls import scale_loads as scale_loads
from ._equilibrium import Solution as Solution
from ._equilibrium import check_converged as check_converged
from ._equilibrium import equilibrium as equilibrium
from ._dynamics import AbstractTimeFunction as AbstractTimeFunction
from ._dynamics import Damping as Damping
from ._dynamics import DynamicLoad as DynamicLoad
from ._dynamics import HarmonicFunction as HarmonicFunction
from ._dynamics import History as History
from ._dynamics import MassProperties as MassProperties
from ._dynamics import Modes as Modes
from ._dynamics import RampFunction as RampFunction
from ._dynamics import StepFunction as StepFunction
from ._dynamics import SupportMotion as SupportMotion
from ._dynamics import TableFunction as TableFunction
from ._dynamics import dynamic_load as dynamic_load
from ._dynamics import mass_matrix as mass_matrix
from ._dynamics import mass_properties as mass_properties
from ._dynamics import modes as modes
from ._dynamics import simulate_dynamics as simulate_dynamics
from ._elements import ElementParameters as ElementParameters
from ._elements import ElementTopology as ElementTopology
from ._elements import FixedPoint as FixedPoint
from ._elements import Line as Line
from ._elements import PointMass as PointMass
from ._elements import PointNode as PointNode
from ._elements import Pulley as Pulley
from ._io.kite_fem import KiteFemImport as KiteFemImport
from ._io.kite_fem import hang_kite as hang_kite
from ._io.kite_fem import hang_program as hang_program
from ._io.kite_fem import hang_until_converged as hang_until_converged
from ._io.kite_fem import import_kite_fem as import_kite_fem
from ._io.kite_fem import restart_from as restart_from
from ._io.kite_fem import scale_gravity_and_loads as scale_gravity_and_loads
from ._io.kite_fem import undeformed_start as undeformed_start
from ._io.kite_fem import write_positions_csv as write_positions_csv
from ._io.kite_fem_reader import KiteFemFormatError as KiteFemFormatError
from ._io.kite_fem_reader import KiteFemModel as KiteFemModel
from ._io.kite_fem_reader import read_kite_fem as read_kite_fem
from ._io.kite_fem_reader import read_kite_fem_positions as read_kite_fem_positions
from ._io.kite_fem_report import kite_fem_line_table as kite_fem_line_table
from ._io.kite_fem_report import kite_fem_reference_positions as kite_fem_reference_positions
from ._io.kite_fem_report import weight_and_reactions as weight_and_reactions
from ._laws import AbstractMomentLaw as AbstractMomentLaw
from ._laws import CurvatureScaledLaw as CurvatureScaledLaw
from ._laws import ScaledLaw as ScaledLaw
from ._laws import EmpiricalBendingLaw2011 as EmpiricalBendingLaw2011
from ._laws import EmpiricalTorsionLaw2011 as EmpiricalTorsionLaw2011
from ._laws import LinearLaw as LinearLaw
from ._laws import ReinforcedLaw as ReinforcedLaw
from ._laws import SplineLaw as SplineLaw
from ._laws import TensionFieldLaw as TensionFieldLaw
from ._mechanics import Configuration as Configuration
from ._mechanics import configuration as configuration
from ._mechanics import initial_state as initial_state
from ._mechanics import reference_geometry as reference_geometry
from ._mechanics import total_energy as total_energy
from ._members import each_member as each_member
from ._members import map_members as map_members
from ._path import DrivenEquilibrium as DrivenEquilibrium
from ._path import drive_to_dead_load as drive_to_dead_load
from ._path import node_dead_load as node_dead_load
from ._path import solve_path as solve_path
from ._path import with_node_dead_load as with_node_dead_load
from ._plot import deformed_shape_figure as deformed_shape_figure
from ._plot import force_deflection_figure as force_deflection_figure
from ._problems import Problem as Problem
from ._problems import ProblemReport as ProblemReport
from ._rotation import rotation_matrix as rotation_matrix
from ._rotation import rotation_vector as rotation_vector
from ._solver import RESULT_MESSAGES as RESULT_MESSAGES
from ._solver import RESULTS as RESULTS
from ._solver import EquilibriumResult as EquilibriumResult
from ._solver import NewtonKKT as NewtonKKT
from ._solver import solve_equilibrium as solve_equilibrium
from ._solver import result_messages as result_messages
from ._spec import LoadedSpec as LoadedSpec
from ._spec import SpecError as SpecError
from ._spec import load_spec as load_spec
from ._structure import Connection as Connection
from ._structure import InertiaParameters as InertiaParameters
from ._structure import SpringJointTopology as SpringJointTopology
from ._structure import Strut as Strut
from ._structure import Structure as Structure
from ._structure import StructureParameters as StructureParameters
from ._structure import Support as Support
from ._structure import Tube as Tube
from ._structure import TubeKite as TubeKite
from ._structure import arc_through_tips as arc_through_tips
from ._structure import air_density as air_density
from ._structure import arc_tube as arc_tube
from ._structure import build_structure as build_structure
from ._structure import cantilever as cantilever
from ._structure import double_taper as double_taper
from ._structure import polyline_tube as polyline_tube
from ._structure import straight_tube as straight_tube
from ._units import UNITS as UNITS
from ._units import unit_factor as unit_factor
from ._version import __version__ as __version__

#: Every public name of the engine (the API reference is generated from this list).
__all__ = [
    "enable_compilation_cache", "disable_traced_program_store", "enable_traced_program_store",
    "stored_jit", "DisplacementControl", "ForceControl", "scale_loads", "Solution",
    "check_converged", "equilibrium", "ElementParameters", "ElementTopology", "FixedPoint",
    "Line", "PointMass", "PointNode", "Pulley", "KiteFemImport", "hang_kite", "hang_program",
    "hang_until_converged", "import_kite_fem", "restart_from", "scale_gravity_and_loads",
    "undeformed_start", "write_positions_csv", "KiteFemFormatError", "KiteFemModel",
    "read_kite_fem", "read_kite_fem_positions", "kite_fem_line_table",
    "kite_fem_reference_positions", "weight_and_reactions", "AbstractMomentLaw",
    "CurvatureScaledLaw", "ScaledLaw", "EmpiricalBendingLaw2011", "EmpiricalTorsionLaw2011",
    "LinearLaw", "ReinforcedLaw", "SplineLaw", "TensionFieldLaw", "Configuration",
    "configuration", "initial_state", "reference_geometry", "total_energy", "each_member",
    "map_members", "DrivenEquilibrium", "drive_to_dead_load", "node_dead_load", "solve_path",
    "with_node_dead_load", "deformed_shape_figure", "force_deflection_figure", "Problem",
    "ProblemReport", "rotation_matrix", "rotation_vector", "RESULT_MESSAGES", "RESULTS",
    "EquilibriumResult", "NewtonKKT", "solve_equilibrium", "result_messages", "LoadedSpec",
    "SpecError", "load_spec", "Connection", "SpringJointTopology", "Strut", "Structure",
    "StructureParameters", "Support", "Tube", "TubeKite", "arc_through_tips", "arc_tube",
    "build_structure", "cantilever", "double_taper", "polyline_tube", "straight_tube", "UNITS",
    "unit_factor", "InertiaParameters", "air_density", "MassProperties", "mass_matrix",
    "mass_properties", "Modes", "modes", "Damping", "History", "simulate_dynamics",
    "AbstractTimeFunction", "DynamicLoad", "HarmonicFunction", "RampFunction", "StepFunction",
    "SupportMotion", "TableFunction", "dynamic_load",
]
