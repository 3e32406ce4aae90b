"""Calibration of jaxtube models against measured force-deflection curves."""

from ._data import DataError as DataError
from ._data import DataProblem as DataProblem
from ._data import MeasuredCurve as MeasuredCurve
from ._data import MeasuredData as MeasuredData
from ._data import load_measurements as load_measurements
