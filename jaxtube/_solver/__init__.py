"""The Newton-KKT equilibrium solver and the vocabulary of its outcomes (re-exports)."""

from .newton_kkt import RESULT_MESSAGES as RESULT_MESSAGES
from .newton_kkt import EquilibriumResult as EquilibriumResult
from .newton_kkt import NewtonKKT as NewtonKKT
from .newton_kkt import solve_equilibrium as solve_equilibrium
from .results import RESULTS as RESULTS
from .results import result_messages as result_messages
