"""Synthetic measured curves from the continuum reference solver (the data format of
:func:`fitting.load_measurements`).
"""

from __future__ import annotations

import csv
import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from .cantilever import CantileverModel

# ---------------------------------------------------------------------------------------
# Synthetic datasets


@dataclasses.dataclass(frozen=True)
class CurveSpec:
    """One synthetic curve: a model evaluated at prescribed deflections.

    Attributes:
        name: the ``curve`` column.
        model: the cantilever model.
        deflections_mm: prescribed (noise-free) tip deflections [mm].
        pressure_bar, radius_m: metadata columns (the model does not read them).
    """

    name: str
    model: CantileverModel
    deflections_mm: Sequence[float]
    pressure_bar: float
    radius_m: float


def prescribed_deflections(
    model: CantileverModel, max_load: float, num_points: int = 25
) -> np.ndarray:
    """``num_points`` evenly spaced deflections [mm] from ``d/num_points`` up to the
    deflection ``d`` at tip load ``max_load`` [N] (e.g. 0.93 x Comer-Levy collapse)."""
    largest = model.tip_deflection(max_load) * 1e3
    return largest * np.arange(1, num_points + 1) / num_points


_COLUMNS = ("curve", "setup", "pressure_bar", "radius_m", "length_m", "deflection_mm", "force_N")


def make_dataset(
    curves: Sequence[CurveSpec],
    noise_force_N: float,
    noise_deflection_mm: float,
    seed: int,
    path=None,
) -> list[dict]:
    """Long-format rows ``curve,setup,pressure_bar,radius_m,length_m,deflection_mm,force_N``.

    Each model is evaluated (displacement control) at its prescribed deflections; then
    independent Gaussian noise of standard deviation ``noise_deflection_mm`` [mm] and
    ``noise_force_N`` [N] is added to the deflection and force columns, as in the shared
    ``cantilever_shear.csv``. Setup is ``cantilever_tip``. Deflections are rounded to
    1 um and forces to 0.1 mN. When ``path`` is given the rows are also written there as
    CSV.
    """
    rng = np.random.default_rng(seed)
    rows = []
    for spec in curves:
        deflections_mm = np.asarray(spec.deflections_mm, dtype=float)
        forces = spec.model.curve(deflections_mm * 1e-3)
        noisy_deflections = deflections_mm + noise_deflection_mm * rng.standard_normal(
            deflections_mm.shape
        )
        noisy_forces = forces + noise_force_N * rng.standard_normal(forces.shape)
        for deflection, force in zip(noisy_deflections, noisy_forces):
            rows.append(
                {
                    "curve": spec.name,
                    "setup": "cantilever_tip",
                    "pressure_bar": spec.pressure_bar,
                    "radius_m": spec.radius_m,
                    "length_m": spec.model.length,
                    "deflection_mm": round(float(deflection), 3),
                    "force_N": round(float(force), 4),
                }
            )
    if path is not None:
        with open(path, "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=_COLUMNS)
            writer.writeheader()
            for row in rows:
                writer.writerow(
                    {
                        **row,
                        "deflection_mm": f"{row['deflection_mm']:.3f}",
                        "force_N": f"{row['force_N']:.4f}",
                    }
                )
    return rows


def noise_floor(curves: Sequence[CurveSpec], rows: Sequence[dict]) -> float:
    """The noise floor [N] of a synthetic dataset: the RMSE of the noise-free truth (each
    curve's model) at the recorded, noisy deflections against the recorded forces (``rows``
    of :func:`make_dataset`): the smallest RMSE any model of force at measured deflection
    can reach."""
    squares = []
    for spec in curves:
        mine = [row for row in rows if row["curve"] == spec.name]
        recorded = np.array([row["deflection_mm"] for row in mine]) * 1e-3
        force = np.array([row["force_N"] for row in mine])
        squares.extend((spec.model.curve(recorded) - force) ** 2)
    return math.sqrt(float(np.mean(squares)))
