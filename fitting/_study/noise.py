"""The model-free noise estimate (:func:`fitting.estimate_noise_with_error`) against each
design's noise floor, without a diagnosis: only the design's data are made, so hundreds of
designs take minutes (:func:`noise_estimate_errors`, ``experiments/diagnosis_study.py
--noise-only``).

What a design can support: the estimate pools the squares of a few dozen pseudo-residuals, so
even on curves that are exactly polynomial it scatters about the realised noise. Its
*sampling ceiling* (:func:`sampling_ceiling`) is the share of white-noise draws at the
design's own deflections whose estimate lies within the tolerance of their realised RMS (the
floor's definition): the best any use of that estimator can do on that design, bias aside.
A design with a ceiling below the target share cannot meet it, whatever the curves; the
summary reports the share within tolerance over all designs and over those whose ceiling
reaches the target.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from .._calibrate.noise import _difference_rows, estimate_noise_with_error
from .designs import StudyDesign, make_design_data


class _Curve(NamedTuple):
    deflection: np.ndarray  # [m]
    force: np.ndarray  # [N]


def sampling_ceiling(curves, order: int, within: float = 0.25, draws: int = 200,
                     seed: int = 0) -> float | None:
    """The share of ``draws`` white-noise samples at the deflections of ``curves`` whose
    estimate of ``order`` is within ``within`` (relative) of the sample's realised RMS: what
    the design's size and spacing allow, with no curve to bias the estimate (module
    docstring). None where the curves are too short for that order."""
    rows = [_difference_rows(np.sort(np.asarray(c.deflection, float)), order) for c in curves]
    windows = sum(r.shape[0] for r in rows)
    if windows == 0:
        return None
    rng = np.random.default_rng(seed)
    noise = [rng.standard_normal((draws, r.shape[1])) for r in rows]  # [draws, n] per curve
    squares = sum(np.sum((e @ r.T) ** 2, axis=1) for e, r in zip(noise, rows))  # [draws]
    realised = np.sqrt(np.mean(np.concatenate(noise, axis=1) ** 2, axis=1))
    return float(np.mean(np.abs(np.sqrt(squares / windows) / realised - 1.0) <= within))


def noise_estimate_errors(design: StudyDesign, orders: Sequence[int] = (1, 2, 3)) -> dict:
    """The design's noise floor [N] and, per difference order, the estimate over the floor
    minus 1 (``error_order_<k>``; None where the curves are too short for that order) and the
    design's sampling ceiling for a 25 % tolerance (``ceiling_order_<k>``,
    :func:`sampling_ceiling`)."""
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
        record[f"ceiling_order_{order}"] = sampling_ceiling(arrays, order)
    return record


def noise_summary(records, within: float = 0.25, target: float = 0.95) -> dict:
    """Per difference order: how many designs, the share whose estimate is within ``within``
    of the floor (None: no design), quantiles of the relative error, and the same share over
    the designs whose sampling ceiling reaches ``target`` (``supported``: how many;
    ``within_supported``; None where no record has a ceiling or none reaches it)."""
    out = {}
    for key in sorted({k for r in records for k in r if k.startswith("error_order_")}):
        order = key.removeprefix("error_")
        kept = [r for r in records if r.get(key) is not None]
        errors = np.array([r[key] for r in kept])
        inside = np.abs(errors) <= within
        supported = np.array([(r.get(f"ceiling_{order}") or 0.0) >= target for r in kept],
                             dtype=bool)
        out[order] = {
            "designs": int(errors.size),
            "within": float(np.mean(inside)) if errors.size else None,
            "supported": int(supported.sum()),
            "within_supported": float(np.mean(inside[supported])) if supported.any() else None,
            **({f"q{int(q * 100):02d}": float(np.quantile(errors, q))
                for q in (0.05, 0.25, 0.5, 0.75, 0.95)} if errors.size else {})}
    return out
