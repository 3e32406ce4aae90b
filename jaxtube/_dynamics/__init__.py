"""Dynamics on the static model's energy (issue 37): inertia, natural modes, time response.

- :mod:`.inertia`: the segments' and points' mass and rotational inertia, the kinetic
  energy in maximal coordinates and the mass matrix of the solver's state;
- :mod:`.modes`: natural modes at an equilibrium (:func:`modes`);
- :mod:`.integrator`: the time response (:func:`simulate_dynamics`), each step's linear
  algebra in :mod:`.step_system`; loads and support motions in time in :mod:`.loads`.
"""

from .inertia import MassProperties as MassProperties
from .inertia import mass_matrix as mass_matrix
from .inertia import mass_properties as mass_properties
from .integrator import Damping as Damping
from .integrator import History as History
from .integrator import simulate_dynamics as simulate_dynamics
from .loads import AbstractTimeFunction as AbstractTimeFunction
from .loads import DynamicLoad as DynamicLoad
from .loads import HarmonicFunction as HarmonicFunction
from .loads import RampFunction as RampFunction
from .loads import StepFunction as StepFunction
from .loads import SupportMotion as SupportMotion
from .loads import TableFunction as TableFunction
from .loads import dynamic_load as dynamic_load
from .modes import Modes as Modes
from .modes import modes as modes
