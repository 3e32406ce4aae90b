"""Calibration of jaxtube models against measured force-deflection curves.

One public namespace: measured data (:func:`load_measurements`), the bench models
(:class:`CantileverRig`), the pivot scaling (:class:`PivotScaling`), the fit (:func:`fit`,
:class:`FitOptions`, :class:`FitResult`), the parameters file (:func:`load_law`), the
comparison with measurements (:func:`compare`), effects (:class:`Effect` and the built-ins)
and the diagnosis of what is missing (:func:`diagnose`, :func:`score_test`), and shapes
against measured markers (:func:`load_markers`, :class:`TubeSurfaces`, :func:`register`,
:func:`marker_rms`, :func:`score_shape`), and campaigns of measured kite shapes
(:func:`read_campaign`, :class:`CaseSolver`).
The independent continuum reference solver is :mod:`fitting.continuum`; the command line is
:mod:`fitting._cli` (``jaxtube``).
"""

import jaxtube as _jt

from ._bench.effects import (
    BUILT_IN_EFFECTS,
    MODEL_EXTENSIONS,
    ClampCompliance,
    Effect,
    EffectParameter,
    RadiusScaling,
    Reinforcement,
    SelfWeight,
    Shear,
    UnwrinkledLinearity,
)
from ._bench.rig import DEFAULT_SEGMENTS, CantileverRig, RigPrediction, TubeModel, batch_curves
from ._bench.scaling import (
    PivotScaling,
    initial_vector,
    reference_specimen,
    wall_stiffness_estimates,
)
from ._calibrate.fit import fit, fit_problem
from ._calibrate.noise import NoiseEstimate, estimate_noise, estimate_noise_with_error
from ._calibrate.parameters_file import load_law
from ._calibrate.problem import (
    Convergence,
    FitError,
    FitOptions,
    Prior,
    make_problem,
)
from ._calibrate.result import FitResult, ParameterEstimate
from ._campaign.calibrate import CampaignCalibration, calibrate_campaign
from ._campaign.diagnose import ShapeCandidateRanking, ShapeDiagnosis, diagnose_campaign
from ._campaign.diagnosis_report import diagnosis_report
from ._campaign.effects import ShapeEffect, resolve_shape_effect, shape_effects
from ._campaign.file import (
    Campaign,
    CampaignCase,
    CaseLoad,
    HangSchedule,
    read_campaign,
)
from ._campaign.kite import (
    campaign_lengths,
    campaign_tube_surfaces,
    import_campaign_case,
    is_offset,
    line_set_rows,
    model_value,
    search_coordinates,
    with_model_values,
    with_values,
)
from ._campaign.model import CampaignError, KiteModel, read_model_file
from ._campaign.solve import CaseSolution, CaseSolver
from ._cluster import open_client as open_cluster_client
from ._data import DataError, DataProblem, MeasuredCurve, MeasuredData, load_measurements
from ._diagnose.compare import Comparison, Group, ResidualVerdict, compare
from ._diagnose.diagnosis import Diagnosis, DiagnosisStep, diagnose
from ._diagnose.ranking import CandidateRanking, DiagnoseOptions, default_candidates
from ._diagnose.restart import BaselineRestart
from ._diagnose.score import (
    ScoreTest,
    likelihood_ratio_p_value,
    score_test,
)
from ._diagnose.validation import CrossValidation, blocked_cross_validation
from ._figures.plots import (
    before_after_figure,
    draw_ranking,
    draw_rmse_per_curve,
    fit_figure,
    ranking_figure,
    where_it_fails_figure,
)
from ._figures.study import study_figure
from ._json import json_ready, write_json
from ._search import BoundedSearch, bounded_search
from ._shape.files import (
    ShapeFileError,
    ShapeFileProblem,
    load_positions,
    load_triangles,
    load_tubes,
)
from ._shape.markers import MarkerSet, load_markers, spanwise_family
from ._shape.registration import (
    MarkerDistances,
    Registration,
    RegistrationResult,
    marker_distances,
    marker_rms,
    register,
)
from ._shape.score import ShapeScore, score_shape
from ._shape.smooth import SmoothScore, continuous_radius, smooth_shape_score
from ._shape.surfaces import TubeSurfaces
from ._study.designs import DesignData, StudyDesign, make_design_data
from ._study.designs import draw_design as draw_study_design
from ._study.noise import noise_estimate_errors, noise_summary
from ._study.run import diagnose_design, run_study
from ._study.run import stored_record as stored_study_record
from ._study.summary import study_report, study_summary
from ._sweep.cluster import sweep_on_cluster
from ._sweep.result import SweepResult, SweepSettings
from ._sweep.status import STATUS_MESSAGES, SweepStatus
from ._sweep.sweep import regime_boundaries, sweep

__all__ = [
    "BUILT_IN_EFFECTS", "MODEL_EXTENSIONS", "ClampCompliance", "Effect", "EffectParameter",
    "RadiusScaling", "Reinforcement", "SelfWeight", "Shear", "ScoreTest", "score_test",
    "UnwrinkledLinearity",
    "BaselineRestart", "CandidateRanking", "Comparison", "DiagnoseOptions", "Diagnosis",
    "DiagnosisStep", "Group",
    "ResidualVerdict", "compare", "default_candidates", "diagnose",
    "fit_problem",
    "before_after_figure", "fit_figure", "ranking_figure", "where_it_fails_figure",
    "CantileverRig", "Convergence", "DEFAULT_SEGMENTS", "DataError", "DataProblem",
    "FitError", "FitOptions", "FitResult", "MeasuredCurve", "MeasuredData",
    "ParameterEstimate", "PivotScaling", "Prior", "RigPrediction", "TubeModel",
    "batch_curves", "estimate_noise", "fit", "initial_vector", "load_law",
    "NoiseEstimate", "estimate_noise_with_error",
    "CrossValidation", "blocked_cross_validation", "likelihood_ratio_p_value",
    "load_measurements", "make_problem", "reference_specimen", "wall_stiffness_estimates",
    "draw_ranking", "draw_rmse_per_curve",
    "MarkerDistances", "MarkerSet", "Registration", "RegistrationResult", "ShapeFileError",
    "ShapeFileProblem", "ShapeScore", "TubeSurfaces", "load_markers", "load_positions",
    "load_triangles", "load_tubes", "marker_distances", "marker_rms", "register",
    "score_shape", "spanwise_family",
        "BoundedSearch", "bounded_search",
    "DesignData", "StudyDesign", "diagnose_design", "draw_study_design", "make_design_data",
    "open_cluster_client", "run_study", "stored_study_record", "study_figure", "study_report",
    "study_summary", "sweep_on_cluster", "json_ready", "write_json", "noise_estimate_errors",
    "noise_summary",
    "CampaignCalibration", "calibrate_campaign",
    "Campaign", "CampaignCase", "CampaignError", "CaseLoad", "CaseSolution", "CaseSolver",
    "HangSchedule", "KiteModel", "campaign_lengths", "campaign_tube_surfaces",
    "import_campaign_case", "is_offset", "search_coordinates", "line_set_rows", "model_value",
    "read_campaign",
    "read_model_file", "with_model_values", "with_values", "SmoothScore", "continuous_radius",
    "smooth_shape_score", "ShapeCandidateRanking", "ShapeDiagnosis", "ShapeEffect",
    "diagnose_campaign", "diagnosis_report", "resolve_shape_effect", "shape_effects",
    "STATUS_MESSAGES", "SweepStatus", "SweepResult", "SweepSettings", "regime_boundaries", "sweep",
]

#: The package version: one number for the engine and the workbench.
__version__ = _jt.__version__
