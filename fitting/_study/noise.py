"""The model-free noise estimate (:func:`fitting.estimate_noise_with_error`) against each
design's noise floor, without a diagnosis: only the design's data are made, so hundreds of
designs take minutes (:func:`noise_estimate_errors`, ``experiments/diagnosis_study.py
--noise-only``)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from .._calibrate.noise import estimate_noise_with_error
from .designs import StudyDesign, make_design_data


class _Curve(NamedTuple):
    deflection: np.ndarray  # [m]
    force: np.ndarray  # [N]


def noise_estimate_errors(design: StudyDesign, orders: Sequence[int] = (1, 2, 3)) -> dict:
    """The design's noise floor [N] and, per difference order, the estimate over the floor
    minus 1 (``error_order_<k>``; None where the curves are too short for that order)."""
    made = make_design_data(design, with_snr=False)
    curves = {}
    for row in made.rows:
        curve = curves.setdefault(row["curve"], {"deflection": [], "force": []})
        curve["deflection"].append(row["deflection_mm"] * 1e-3)
        curve["force"].append(row["force_N"])
    arrays = [_Curve(np.asarray(c["deflection"]), np.asarray(c["force"]))
              for c in curves.values()]
    record = {"name": design.name, "design": design.to_json(), "curves": len(arrays),
              "noise_floor_N": made.noise_floor_N}
    for order in orders:
        estimate = estimate_noise_with_error(arrays, order=order)
        record[f"error_order_{order}"] = (None if estimate is None or estimate.order != order
                                          else estimate.noise_N / made.noise_floor_N - 1.0)
    return record


def noise_summary(records, within: float = 0.25) -> dict:
    """Per difference order: how many designs, the share whose estimate is within ``within``
    of the floor (None: no design), and quantiles of the relative error."""
    out = {}
    for key in sorted({k for r in records for k in r if k.startswith("error_order_")}):
        errors = np.array([r[key] for r in records if r.get(key) is not None])
        out[key.removeprefix("error_")] = {
            "designs": int(errors.size),
            "within": float(np.mean(np.abs(errors) <= within)) if errors.size else None,
            **({f"q{int(q * 100):02d}": float(np.quantile(errors, q))
                for q in (0.05, 0.25, 0.5, 0.75, 0.95)} if errors.size else {})}
    return out
