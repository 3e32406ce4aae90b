"""A campaign's cases solved and written: ``compare`` (the solved shapes against their
markers and measured lengths) and ``predict`` (every node of every case).

**compare** (:func:`compare_cases`, :func:`write_comparison`), for each case with markers:
the peers' metric (RMS over the tube markers of the tube-surface distance after rigid
registration, :func:`fitting.score_shape`), per marker group and per marker, the canopy
markers apart, the undeformed kite scored the same way (the null model), the measured
lengths against the model's. Files: ``cases.csv``, ``groups.csv``, ``markers.csv``,
``lengths.csv``, ``comparison.json`` and the figures ``rms_per_case.png`` (each case's RMS
beside the undeformed kite's and the published numbers) and ``<case>_shape.png`` (the
registered markers on the solved shape, coloured by error, beside the undeformed kite).

**predict** (:func:`write_predictions`): ``DIR/<case>/positions.csv`` (``node,x_m,y_m,z_m``,
every node of the model file in its numbering and frame; not written when the solve did not
converge) and ``DIR/<case>/summary.json`` (``converged``, ``seconds`` warm, the Newton
steps, the route, the model's values).

JSON carries no NaN (``null``); every number is in the unit its name says.
"""

from __future__ import annotations

import csv
import json
import math
import os

import numpy as np
from matplotlib.figure import Figure

import jaxtube as jt

from .._shape.figure import shape_figure
from .._shape.markers import load_markers
from .._shape.score import MARKER_CSV_COLUMNS, ShapeScore, score_shape
from .file import Campaign
from .kite import campaign_lengths, campaign_tube_surfaces
from .model import KiteModel
from .solve import CaseSolution, CaseSolver


def _finite(value):
    """``value`` for JSON: NaN and infinities become ``None``."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def compare_cases(campaign: Campaign, model: KiteModel, cases, solver: CaseSolver,
                  log=print) -> list[dict]:
    """Solve and score ``cases`` (names; each must have markers). Returns one record per
    case: ``solved`` (:class:`CaseSolution`), ``score`` and ``undeformed``
    (:class:`fitting.ShapeScore`), ``lengths`` (``{name: (measured, model, undeformed)}``
    [m])."""
    undeformed_surfaces = campaign_tube_surfaces(campaign)
    undeformed_lengths = campaign_lengths(campaign, campaign.kite_fem.node_position)
    records = []
    for name in cases:
        case = campaign.case(name)
        markers = load_markers(case.markers)
        solved = solver.solve(case, model)
        score = score_shape(campaign_tube_surfaces(campaign, solved.positions), markers,
                            canopy_group=campaign.canopy_group)
        null = score_shape(undeformed_surfaces, markers, canopy_group=campaign.canopy_group)
        computed = campaign_lengths(campaign, solved.positions)
        lengths = {n: (v, computed[n], undeformed_lengths[n])
                   for n, v in case.measured_lengths_m.items()}
        records.append(dict(solved=solved, score=score, undeformed=null, lengths=lengths))
        log(f"{name}: RMS {score.rms_mm:.1f} mm (undeformed {null.rms_mm:.1f}), converged "
            f"{solved.converged}, Newton {solved.newton_iterations}, warm {solved.seconds:.2f} s")
    return records


def case_row(record) -> dict:
    """One row of ``cases.csv`` (and of ``comparison.json``)."""
    solved: CaseSolution = record["solved"]
    score: ShapeScore = record["score"]
    lengths = record["lengths"]
    relative = [abs(model - measured) / measured for measured, model, _ in lengths.values()]
    relative_null = [abs(null - measured) / measured for measured, _, null in lengths.values()]
    case = solved.case
    return {"case": case.name, "role": case.role, "pressure_bar": case.pressure_bar,
            "rms_mm": score.rms_mm, "undeformed_rms_mm": record["undeformed"].rms_mm,
            "canopy_rms_mm": score.canopy_rms_mm,
            "length_mean_relative_error": float(np.mean(relative)) if relative else None,
            "undeformed_length_mean_relative_error":
                float(np.mean(relative_null)) if relative_null else None,
            "converged": solved.converged, "seconds": solved.seconds,
            "registration_converged": score.registration.converged,
            "spanwise_order_reversed": score.registration.registration.reversed_order,
            **{f"published_{k}_mm": v for k, v in case.published_rms_mm.items()}}


def rms_figure(records, path, model_label: str) -> None:
    """Bars of each case's RMS [mm]: undeformed, the published numbers, this model."""
    names = [r["solved"].case.name for r in records]
    sources = list(dict.fromkeys(k for r in records for k in r["solved"].case.published_rms_mm))
    series = [("undeformed", [r["undeformed"].rms_mm for r in records])]
    series += [(f"published: {s}", [r["solved"].case.published_rms_mm.get(s, np.nan)
                                    for r in records]) for s in sources]
    series.append((model_label, [r["score"].rms_mm for r in records]))
    width = 0.8 / len(series)
    figure = Figure(figsize=(1.6 * len(names) + 3, 4))
    axes = figure.add_subplot()
    for k, (label, values) in enumerate(series):
        axes.bar(np.arange(len(names)) + (k - (len(series) - 1) / 2) * width, values, width,
                 label=label)
    axes.set_xticks(np.arange(len(names)), names)
    axes.set_ylabel("RMS marker distance to tube surface [mm]")
    axes.set_yscale("log")
    axes.legend(fontsize=7)
    figure.tight_layout()
    figure.savefig(path, dpi=120)


def comparison_writers(campaign: Campaign, model: KiteModel, records, figures=True) -> dict:
    """``{file name: writer(path)}`` of ``compare`` (module docstring)."""
    rows = [case_row(r) for r in records]

    def write_csv(header, table):
        def write(path):
            with open(path, "w", newline="") as handle:
                writer = csv.writer(handle)
                writer.writerow(header)
                for row in table:
                    writer.writerow(["" if v is None or (isinstance(v, float) and v != v)
                                     else v for v in row])
        return write

    columns = list(dict.fromkeys(k for row in rows for k in row))
    writers = {
        "cases.csv": write_csv(columns, [[row.get(c) for c in columns] for row in rows]),
        "groups.csv": write_csv(("case", "group", "rms_mm", "undeformed_rms_mm"), [
            (r["solved"].case.name, g, v, r["undeformed"].group_rms_mm.get(g))
            for r in records for g, v in r["score"].group_rms_mm.items()]),
        "markers.csv": write_csv(("case",) + MARKER_CSV_COLUMNS, [
            (r["solved"].case.name, *row) for r in records for row in r["score"].marker_rows()]),
        "lengths.csv": write_csv(("case", "length", "measured_m", "model_m", "undeformed_m"), [
            (r["solved"].case.name, n, *v) for r in records for n, v in r["lengths"].items()]),
        "comparison.json": lambda path: path.write_text(json.dumps(_finite({
            "campaign": str(campaign.path), "model": model.to_json(),
            "metric": "RMS over tube markers of the tube-surface distance after rigid "
                      "registration (the peers' metric); canopy markers apart",
            "cases": [dict(row, group_rms_mm=r["score"].group_rms_mm,
                           registration=r["score"].summary()["registration"],
                           newton_iterations=r["solved"].newton_iterations,
                           hang=r["solved"].hang, drive=r["solved"].drive,
                           lengths_m={n: dict(zip(("measured", "model", "undeformed"), v))
                                      for n, v in r["lengths"].items()})
                      for row, r in zip(rows, records)],
            "load_average": list(os.getloadavg())}), indent=2) + "\n"),
    }
    if figures:
        writers["rms_per_case.png"] = lambda path: rms_figure(records, path, "jaxtube")
        undeformed = campaign_tube_surfaces(campaign)
        for r in records:
            writers[f"{r['solved'].case.name}_shape.png"] = (
                lambda path, r=r: shape_figure(
                    r["score"], campaign_tube_surfaces(campaign, r["solved"].positions), path,
                    null=r["undeformed"], undeformed=undeformed))
    return writers


def prediction_writers(solved: CaseSolution, model: KiteModel, campaign: Campaign) -> dict:
    """``{file name: writer(path)}`` of one case's ``predict`` folder (module docstring)."""
    case = solved.case
    summary = {"case": case.name, "converged": solved.converged,
               "seconds": round(solved.seconds, 4),
               "compile_seconds": round(solved.compile_seconds, 2),
               "newton_iterations": solved.newton_iterations,
               "stage_converged": solved.stage_converged, "hang": solved.hang,
               "drive": solved.drive, "pressure_bar": case.pressure_bar,
               "loads": [{"node": load.node, "force_N": load.force_N.tolist()}
                         for load in case.loads],
               "model": model.to_json(), "campaign": str(campaign.path),
               "load_average": list(os.getloadavg())}
    writers = {"summary.json": lambda path: path.write_text(
        json.dumps(_finite(summary), indent=2) + "\n")}
    if solved.converged:
        writers["positions.csv"] = lambda path: jt.write_positions_csv(path, solved.positions)
    return writers


def rms_before_after_figure(before: dict, after: dict, path) -> None:
    """Bars of each case's RMS [mm] before and after a calibration."""
    names = list(before)
    figure = Figure(figsize=(1.4 * len(names) + 3, 4))
    axes = figure.add_subplot()
    for k, (label, values) in enumerate((("before", before), ("after", after))):
        axes.bar(np.arange(len(names)) + (k - 0.5) * 0.4, [values[n] for n in names], 0.4,
                 label=label)
    axes.set_xticks(np.arange(len(names)), names)
    axes.set_ylabel("smooth RMS marker distance [mm]")
    axes.legend()
    figure.tight_layout()
    figure.savefig(path, dpi=120)
