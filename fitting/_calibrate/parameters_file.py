"""Reading a parameters file back (format: :mod:`fitting._calibrate.result`): the law for
``jaxtube simulate --params``, and the prediction with its band for ``jaxtube predict``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

import jaxtube as jt

from .._bench.effects import BUILT_IN_EFFECTS, MODEL_EXTENSIONS
from .._bench.rig import CantileverRig
from .._bench.scaling import PivotScaling
from .problem import FitProblem, forces_and_sensitivity, specimen_arrays
from .result import FORMAT, VERSION, _delta_method


def predict_from_document(document: dict, pressure: float, radius: float, length: float,
                          deflection) -> tuple[np.ndarray, np.ndarray]:
    """Cantilever force [N] and its delta-method standard deviation at tip deflections
    ``[P]`` [m], from a parameters file's contents (its law, coordinates and covariance)."""
    known = BUILT_IN_EFFECTS | MODEL_EXTENSIONS
    unknown = [name for name in document.get("effects", {}) if name not in known]
    if unknown:
        raise ValueError(f"the fit used effect(s) {unknown}, which are not built in; predict "
                         "with the Python API (FitResult.predict) instead")
    effects = tuple(known[name] for name in document.get("effects", {}))
    law = document["law"]
    scaling = PivotScaling(form=law["form"], pivots_per_regime=tuple(law["pivots_per_regime"]),
                           residual_stiffness_ratio=float(law["residual_stiffness_ratio"]))
    coordinates = document["coordinates"]
    free_index = tuple(int(i) for i in coordinates["free_index"])
    reference = (float(document["reference"]["pressure_Pa"]),
                 float(document["reference"]["radius_m"]))
    features = frozenset().union(*[e.features for e in effects])
    problem = FitProblem(
        data=None, batch=None, rig=CantileverRig(segments=int(document["segments"]),
                                                 features=features), effects=effects,
        scaling=scaling, reference=reference, names=tuple(coordinates["names"]),
        free_index=free_index, base=np.asarray(coordinates["values"], float),
        lower=None, upper=None, prior_mean=np.zeros(len(coordinates["names"])),
        prior_sd=np.full(len(coordinates["names"]), np.inf),
        noise=float(document["noise_N"]), noise_given=True)
    values = problem.base[np.asarray(free_index)]
    arrays = specimen_arrays([pressure], [radius], [length], np.asarray(deflection)[None])
    force, sens, converged = forces_and_sensitivity(problem, values, arrays)
    if not np.all(converged):
        raise RuntimeError(f"prediction: {int(np.sum(~converged))} equilibrium solves did not "
                           "converge")
    covariance = np.array(document["covariance"], float)
    return force[0], _delta_method(sens, covariance)[0]


def load_law(path) -> jt.SplineLaw:
    """The bending law of a parameters file written by ``jaxtube fit`` (clear errors).

    The file's ``law`` block is the fitted spline; the model-structure extensions the fit
    included (``effects``) are part of the law and folded in here, exactly, each by its
    :meth:`fitting.Effect.law_for_every_specimen` (``unwrinkled_linearity`` sets
    ``linear_share``; ``radius_scaling`` turns a paper-form law into the separate form with
    radius exponents ``3 B_i + D`` and scales ``A_i r_ref^-D``). Physical effects (shear,
    clamp compliance, ...) belong to the tube or the rig, not to the law, and are not
    applied."""
    path = Path(path)
    try:
        document = json.loads(path.read_text())
    except FileNotFoundError:
        raise ValueError(f"{path}: parameters file not found") from None
    except json.JSONDecodeError as error:
        raise ValueError(f"{path}: not valid JSON (line {error.lineno}, column "
                         f"{error.colno}): {error.msg}") from None
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise ValueError(f"{path}: expected a jaxtube fit parameters file "
                         f"(\"format\": \"{FORMAT}\")")
    if document.get("version") != VERSION:
        raise ValueError(f"{path}: unsupported version {document.get('version')!r}; "
                         f"expected {VERSION}")
    law = document.get("law", {})
    if law.get("type") != "SplineLaw":
        raise ValueError(f"{path}: law.type must be 'SplineLaw', got {law.get('type')!r}")
    try:
        spline = jt.SplineLaw(
            curvature_scale=np.asarray(law["curvature_scale"], float),
            curvature_exponent=np.asarray(law["curvature_exponent"], float),
            moment_scale=np.asarray(law["moment_scale"], float),
            moment_exponent=np.asarray(law["moment_exponent"], float),
            curvature_radius_exponent=None if law.get("curvature_radius_exponent") is None
            else np.asarray(law["curvature_radius_exponent"], float),
            moment_radius_exponent=None if law.get("moment_radius_exponent") is None
            else np.asarray(law["moment_radius_exponent"], float),
            residual_stiffness_ratio=float(law.get("residual_stiffness_ratio", 0.01)),
            linear_share=float(law.get("linear_share", 0.0)),
            pivots_per_regime=tuple(int(n) for n in law["pivots_per_regime"]))
        return _with_model_extensions(spline, document.get("effects") or {},
                                      document.get("reference") or {})
    except KeyError as error:
        raise ValueError(f"{path}: law.{error.args[0]} is missing") from None
    except (TypeError, ValueError) as error:
        raise ValueError(f"{path}: invalid law: {error}") from None


def without_effects_words(path) -> str:
    """`` (the fit's X, Y not applied: ...)`` or ``""``: the effects of a parameters file's
    fit that :func:`load_law` does not fold into the law (physical effects: properties of
    the bench rig or the tube), for ``simulate`` and ``sweep`` to name; call after
    :func:`load_law` has validated the file."""
    effects = json.loads(Path(path).read_text()).get("effects") or {}
    left_out = [name for name in effects if name not in MODEL_EXTENSIONS]
    if not left_out:
        return ""
    return (f" (the fit's {', '.join(left_out)} not applied: effects of the bench rig or "
            "tube, not of the law)")


def _with_model_extensions(law: jt.SplineLaw, effects: dict, reference: dict) -> jt.SplineLaw:
    """``law`` with the fitted model-structure extensions folded in (:func:`load_law`)."""
    for name, values in effects.items():
        if name in MODEL_EXTENSIONS:
            effect = MODEL_EXTENSIONS[name](**{k: float(v) for k, v in values.items()})
            law = effect.law_for_every_specimen(law, float(reference["radius_m"]))
    return law
