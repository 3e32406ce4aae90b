"""jaxtube: differentiable simulator of inflatable tubular structures.

The rigid-segment method of Breukels & Ockels (2008) on JAX: tubes are chains of rigid
segments joined by spherical joints whose moments follow nonlinear moment-curvature laws;
equilibrium is found by constrained Newton energy minimisation, and differentiated by the
implicit function theorem.

Float64: Newton tolerances need double precision, so importing jaxtube turns on
``jax_enable_x64`` (documented in the README). Set the environment variable
``JAXTUBE_NO_X64=1`` to keep JAX's default; solves then raise a clear ``TypeError``
instead of silently failing in float32.

Threads: importing jaxtube before JAX has started selects single-threaded XLA CPU kernels
(``--xla_cpu_multi_thread_eigen=false`` in ``XLA_FLAGS``) unless ``XLA_FLAGS`` already sets
that flag or ``JAXTUBE_XLA_THREADS=1`` (README, "Threads").
"""

import os as _os

# Single-threaded XLA CPU (Eigen) kernels unless the user chose: this package's programs are
# many small dense operations, for which intra-op threads only add contention; on 2-core
# machines the default threads made kite solves 16x and diagnoses ~4x slower (README,
# "Threads"). XLA reads the flag when its CPU backend starts, so it takes effect only if
# JAX has not run anything yet. Opt out with JAXTUBE_XLA_THREADS=1, or set the flag yourself.
if ("xla_cpu_multi_thread_eigen" not in _os.environ.get("XLA_FLAGS", "")
        and _os.environ.get("JAXTUBE_XLA_THREADS", "0") in ("", "0")):
    _os.environ["XLA_FLAGS"] = (_os.environ.get("XLA_FLAGS", "")
                                + " --xla_cpu_multi_thread_eigen=false").strip()

import jax as _jax

if _os.environ.get("JAXTUBE_NO_X64", "0") in ("", "0"):
    _jax.config.update("jax_enable_x64", True)

from ._compilation_cache import enable_compilation_cache as enable_compilation_cache
from ._kite import Strut as Strut
from ._kite import TubeKite as TubeKite
from ._kite import arc_through_tips as arc_through_tips
from ._kite import double_taper as double_taper
from ._laws import AbstractMomentLaw as AbstractMomentLaw
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
from ._model import DisplacementControl as DisplacementControl
from ._model import ForceControl as ForceControl
from ._model import Solution as Solution
from ._model import check_converged as check_converged
from ._model import equilibrium as equilibrium
from ._model import scale_loads as scale_loads
from ._model import solve_path as solve_path
from ._model import total_energy as total_energy
from ._results import RESULTS as RESULTS
from ._rotation import rotation_matrix as rotation_matrix
from ._rotation import rotation_vector as rotation_vector
from ._solver import RESULT_MESSAGES as RESULT_MESSAGES
from ._solver import Equilibrium as Equilibrium
from ._solver import NewtonKKT as NewtonKKT
from ._solver import solve_equilibrium as solve_equilibrium
from ._spec import SpecError as SpecError
from ._spec import load_spec as load_spec
from ._structure import Connection as Connection
from ._structure import Structure as Structure
from ._structure import StructureParameters as StructureParameters
from ._structure import Support as Support
from ._structure import Tube as Tube
from ._structure import arc_tube as arc_tube
from ._structure import build_structure as build_structure
from ._structure import cantilever as cantilever
from ._structure import polyline_tube as polyline_tube
from ._structure import straight_tube as straight_tube

__version__ = "0.1.0"
