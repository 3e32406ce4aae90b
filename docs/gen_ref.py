"""The API reference pages, generated from the packages' ``__all__`` at build time.

A MkDocs hook (``hooks:`` in ``mkdocs.yml``). A reference page holds a marker such as
``<!-- reference: jaxtube -->``; :func:`on_page_markdown` replaces it with one
mkdocstrings block (``::: jaxtube.Name``) per name of that package's ``__all__``, grouped by
topic under ``##`` headings. Names that no topic lists go under "Other names", and topics
name only what ``__all__`` holds, so a name added to or removed from ``__all__`` never
breaks the build nor goes missing from the reference (``tests/test_docs_reference.py``).
"""

from __future__ import annotations

import importlib
import re

#: Topic headings and the names they gather, per package, in reading order.
TOPICS: dict[str, dict[str, tuple[str, ...]]] = {
    "jaxtube": {
        "Structures": (
            "Tube", "Support", "Connection", "Strut", "TubeKite", "Structure",
            "StructureParameters", "SpringJointTopology", "build_structure", "cantilever",
            "straight_tube", "arc_tube", "arc_through_tips", "polyline_tube", "double_taper",
        ),
        "Point nodes, lines, pulleys and masses": (
            "PointNode", "FixedPoint", "Line", "Pulley", "PointMass", "ElementTopology",
            "ElementParameters",
        ),
        "Moment-curvature laws": (
            "AbstractMomentLaw", "SplineLaw", "TensionFieldLaw", "EmpiricalBendingLaw2011",
            "EmpiricalTorsionLaw2011", "LinearLaw", "ScaledLaw", "CurvatureScaledLaw",
            "ReinforcedLaw",
        ),
        "Loads and controls": ("ForceControl", "DisplacementControl", "scale_loads"),
        "Equilibrium and load paths": (
            "equilibrium", "Solution", "check_converged", "solve_path", "drive_to_dead_load",
            "DrivenEquilibrium", "node_dead_load", "with_node_dead_load",
        ),
        "Solver": (
            "NewtonKKT", "solve_equilibrium", "EquilibriumResult", "RESULTS",
            "RESULT_MESSAGES", "result_messages",
        ),
        "Many solves at once": ("map_members", "each_member"),
        "Dynamics": (
            "modes", "Modes", "simulate_dynamics", "History", "Damping", "InertiaParameters",
            "air_density", "MassProperties", "mass_properties", "mass_matrix", "DynamicLoad",
            "dynamic_load", "SupportMotion", "AbstractTimeFunction", "StepFunction",
            "RampFunction", "HarmonicFunction", "TableFunction",
        ),
        "Mechanics": (
            "Configuration", "configuration", "initial_state", "reference_geometry",
            "total_energy", "rotation_matrix", "rotation_vector",
        ),
        "Spec files": ("load_spec", "LoadedSpec", "SpecError"),
        "kite_fem models": (
            "read_kite_fem", "KiteFemModel", "KiteFemFormatError", "read_kite_fem_positions",
            "import_kite_fem", "KiteFemImport", "hang_kite", "hang_program",
            "hang_until_converged", "restart_from", "scale_gravity_and_loads",
            "undeformed_start", "write_positions_csv", "kite_fem_line_table",
            "kite_fem_reference_positions", "weight_and_reactions",
        ),
        "Figures": ("force_deflection_figure", "deformed_shape_figure"),
        "Compilation and stored programs": (
            "enable_compilation_cache", "stored_jit", "enable_traced_program_store",
            "disable_traced_program_store",
        ),
        "Units and input problems": ("UNITS", "unit_factor", "Problem", "ProblemReport"),
    },
    "fitting": {
        "Measured data": (
            "load_measurements", "MeasuredData", "MeasuredCurve", "DataError", "DataProblem",
        ),
        "The bench rig and the pivot scaling": (
            "CantileverRig", "TubeModel", "RigPrediction", "batch_curves", "DEFAULT_SEGMENTS",
            "PivotScaling", "initial_vector", "reference_specimen", "wall_stiffness_estimates",
        ),
        "Fitting": (
            "fit", "fit_problem", "make_problem", "FitOptions", "FitResult", "FitError",
            "Convergence", "Prior", "ParameterEstimate", "load_law", "estimate_noise",
            "estimate_noise_with_error", "NoiseEstimate",
        ),
        "Effects": (
            "Effect", "EffectParameter", "BUILT_IN_EFFECTS", "MODEL_EXTENSIONS", "Shear",
            "Reinforcement", "ClampCompliance", "SelfWeight", "RadiusScaling",
            "UnwrinkledLinearity",
        ),
        "Comparison and diagnosis": (
            "compare", "Comparison", "Group", "ResidualVerdict", "diagnose", "Diagnosis",
            "DiagnosisStep", "DiagnoseOptions", "BaselineRestart", "CandidateRanking",
            "default_candidates",
            "score_test", "ScoreTest", "likelihood_ratio_p_value", "blocked_cross_validation",
            "CrossValidation", "cross_validated_rmse",
        ),
        "Figures": (
            "fit_figure", "where_it_fails_figure", "ranking_figure", "before_after_figure",
            "draw_ranking", "draw_rmse_per_curve",
        ),
        "Shapes against markers": (
            "load_markers", "MarkerSet", "spanwise_family", "load_positions", "load_tubes",
            "load_triangles", "ShapeFileError", "ShapeFileProblem", "TubeSurfaces", "register",
            "Registration", "RegistrationResult", "marker_rms", "marker_distances",
            "MarkerDistances", "score_shape", "ShapeScore", "fit_to_markers", "MarkerFit",
        ),
        "Design sweeps": (
            "sweep", "SweepResult", "SweepSettings", "SweepStatus", "STATUS_MESSAGES",
            "regime_boundaries",
        ),
    },
    "fitting.continuum": {},
}

_MARKER = re.compile(r"<!--\s*reference:\s*([\w.]+)\s*-->")


def public_names(package: str) -> list[str]:
    """The names of ``package.__all__``, in its order."""
    return list(importlib.import_module(package).__all__)


def grouped_names(package: str) -> list[tuple[str, list[str]]]:
    """``(heading, names)`` pairs covering every name of ``package.__all__`` exactly once:
    the topics of :data:`TOPICS` (only the names ``__all__`` holds), then "Other names"."""
    names = public_names(package)
    groups, placed = [], set()
    for heading, listed in TOPICS.get(package, {}).items():
        present = [name for name in listed if name in names and name not in placed]
        placed.update(present)
        if present:
            groups.append((heading, present))
    rest = [name for name in names if name not in placed]
    if rest:
        groups.append(("Other names" if groups else "Names", sorted(rest, key=str.lower)))
    return groups


def reference_markdown(package: str) -> str:
    """The Markdown of ``package``'s reference: one ``::: package.Name`` block per name."""
    parts = []
    for heading, names in grouped_names(package):
        parts.append(f"## {heading}\n")
        parts.extend(f"::: {package}.{name}\n" for name in names)
    return "\n".join(parts)


def on_page_markdown(markdown: str, page, config, files) -> str:
    """MkDocs hook: expand every ``<!-- reference: PACKAGE -->`` marker of a page."""
    return _MARKER.sub(lambda match: reference_markdown(match.group(1)), markdown)
