"""One diagnosis-study design set up for fits outside the diagnosis (the scripts that follow
a design's miss: ``pivot_resolution.py``, ``law_ceiling.py``): its data, noise floor, the
diagnosis' candidates and its fit options, every candidate held at its null."""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

import fitting as ft
from fitting._bench.scaling import PivotScaling
from fitting._calibrate.noise import estimate_noise_with_error
from fitting._diagnose.ranking import _fit_options, default_candidates
from fitting._diagnose.score import parameter_names
from fitting._study.designs import make_design_data


def add_design_arguments(parser: argparse.ArgumentParser, index: int) -> None:
    """``--index`` (default ``index``), ``--seed`` and ``--iterations`` (the cap per fit)."""
    parser.add_argument("--index", type=int, default=index,
                        help=f"design index (default {index})")
    parser.add_argument("--seed", type=int, default=0, help="study seed (default 0)")
    parser.add_argument("--iterations", type=int, default=150,
                        help="Levenberg-Marquardt cap per fit (default 150)")


@dataclasses.dataclass(frozen=True)
class DesignSetup:
    """A design (:class:`fitting.StudyDesign`), its data, noise floor [N], the diagnosis'
    candidates and the fit options of its baseline (the model-free noise estimate, the
    candidates held at their null values, ``iterations`` per fit)."""

    design: ft.StudyDesign
    data: ft.MeasuredData
    noise_floor_N: float
    candidates: tuple
    fit_options: object


def design_setup(index: int, seed: int, iterations: int) -> DesignSetup:
    """Design ``index`` of ``seed`` made into data (:func:`fitting.make_design_data`) and
    set up as the diagnosis' baseline sets it up; prints the design's line."""
    design = ft.draw_study_design(index, seed)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "design.csv"
        made = make_design_data(design, path, with_snr=False)
        data = ft.load_measurements(path)
    print(f"{design.name}: {design.specimens}, {design.points} points, hidden "
          f"{dict(design.hidden) or 'none'}, noise floor {made.noise_floor_N:.4g} N")
    candidates = default_candidates(PivotScaling())
    held = {name: p.null for c in candidates
            for name, p in zip(parameter_names(c), c.parameters)}
    fit_options = dataclasses.replace(
        _fit_options(ft.DiagnoseOptions(progress=False),
                     estimate_noise_with_error(data).noise_N, iterations), fixed=held)
    return DesignSetup(design, data, made.noise_floor_N, candidates, fit_options)
