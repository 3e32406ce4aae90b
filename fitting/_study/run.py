"""Running the diagnosis study: one design's diagnosis and its record
(:func:`diagnose_design`), and the designs on a Dask ``distributed`` cluster
(:func:`fitting.open_cluster_client`), each record stored as it ends so that a stopped study
resumes where it stopped (:func:`run_study`). Records are sent back to the client and
written there, so the workers need no shared filesystem.
"""

from __future__ import annotations

import json
import tempfile
import time
import traceback
from collections.abc import Sequence
from pathlib import Path

from .._bench.effects import BUILT_IN_EFFECTS, MODEL_EXTENSIONS
from .._bench.rig import DEFAULT_SEGMENTS, CantileverRig
from .._bench.scaling import PivotScaling
from .._data import load_measurements
from .._diagnose.diagnosis import diagnose
from .._diagnose.ranking import DiagnoseOptions, default_candidates
from .._json import write_json
from .designs import StudyDesign, make_design_data

#: Shapes ``(curves, points, segments, candidates)`` this process has diagnosed: the first
#: diagnosis of a shape compiles its model (or loads it from the persistent compilation
#: cache), later ones run warm; each record says which it was (``warm``).
_SHAPES_SEEN: set = set()
#: Words of the diagnosis' statements that say a candidate cannot be read from the data.
CANNOT_TELL = ("cannot be told apart", "cannot be tested", "can barely be told apart")


def _told_apart_statements(statements, names) -> dict[str, list[str]]:
    """Per effect name, the statements that say it cannot be told apart (or tested)."""
    out: dict[str, list[str]] = {}
    for sentence in statements:
        if any(words in sentence for words in CANNOT_TELL):
            for name in names:
                if name in sentence.split(" with this data")[0]:
                    out.setdefault(name, []).append(sentence)
    return out


def diagnose_design(design: StudyDesign, candidates: Sequence[str] | None = None,
                    segments: int | None = None,
                    baseline_starts: int = DiagnoseOptions.baseline_starts,
                    noise_order: int = DiagnoseOptions.noise_order) -> dict:
    """Make the design's data (:func:`fitting._study.designs.make_design_data`), diagnose it
    and return its record (a JSON-ready dict): the design, its noise floor, each hidden
    effect's signal-to-noise ratio and whether the design can separate it, the verdict, its
    physical effects (``found``), baseline and final RMSE [N], the noise estimate [N],
    convergence, what restarting the baseline did (``baseline_restart``, None: its first fit
    ended inside its box), the "cannot be told apart" statements by effect, seconds (of the
    diagnosis; of making the data) and whether this process had diagnosed the same shape before
    (``warm``: no compilation in those seconds). A diagnosis that raises is recorded with ``error``.

    ``candidates``: names to restrict the candidates to (default: all of
    :func:`fitting.default_candidates`); ``segments``: the model tube's segments;
    ``baseline_starts``, ``noise_order``: those of :class:`fitting.DiagnoseOptions`."""
    scaling = PivotScaling()
    chosen = default_candidates(scaling)
    if candidates is not None:
        chosen = tuple(c for c in chosen if c.name in set(candidates))
    record = {"name": design.name, "design": design.to_json(), "hidden": design.hidden_label,
              "curves": len(design.specimens)}
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"{design.name}.csv"
        made = make_design_data(design, path)
        data = load_measurements(path)
    record.update(noise_floor_N=made.noise_floor_N, snr=made.snr,
                  separable={name: design.separable(name) for name, _ in design.hidden},
                  data_seconds=time.perf_counter() - started)
    shape = (len(design.specimens), design.points, segments, tuple(c.name for c in chosen))
    record["warm"] = shape in _SHAPES_SEEN
    _SHAPES_SEEN.add(shape)
    started = time.perf_counter()
    try:
        diagnosis = diagnose(data, scaling=scaling,
                             rig=CantileverRig(segments=segments or DEFAULT_SEGMENTS),
                             options=DiagnoseOptions(progress=False,
                                                     baseline_starts=baseline_starts,
                                                     noise_order=noise_order),
                             candidates=chosen)
    except Exception as error:  # noqa: BLE001 (recorded: the study goes on)
        record.update(error=f"{type(error).__name__}: {error}",
                      traceback=traceback.format_exc(limit=4),
                      seconds=time.perf_counter() - started)
        return record
    physical = [name for name in diagnosis.verdict if name in BUILT_IN_EFFECTS]
    names = list(BUILT_IN_EFFECTS) + list(MODEL_EXTENSIONS)
    record.update(
        error=None, verdict=list(diagnosis.verdict), found="+".join(sorted(physical)) or "none",
        baseline_rmse_N=diagnosis.baseline.rmse, final_rmse_N=diagnosis.final.rmse,
        noise_N=diagnosis.noise, baseline_converged=diagnosis.baseline.convergence.converged,
        final_converged=diagnosis.final.convergence.converged,
        baseline_restart=(diagnosis.baseline_restart.to_json()
                          if diagnosis.baseline_restart is not None else None),
        cannot_tell=_told_apart_statements(diagnosis.statements, names),
        seconds=time.perf_counter() - started)
    return record


def stored_record(path: Path, design: StudyDesign) -> dict | None:
    """The record stored at ``path`` if it is this design's, else None."""
    if not path.exists():
        return None
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return record if record.get("design") == json.loads(json.dumps(design.to_json())) else None


def run_study(designs: Sequence[StudyDesign], results: Path, client, task=None,
              progress: bool = True, **options) -> tuple[list[dict], int]:
    """Run ``task(design, **options)`` (default :func:`diagnose_design`; a function returning
    a JSON-ready record) for every design on ``client``'s cluster; each record is written to
    ``results/<design name>.json`` as it ends. Designs whose record is already stored are
    not run again. Returns the records in the order of ``designs`` and how many were run."""
    from distributed import as_completed

    results = Path(results)
    results.mkdir(parents=True, exist_ok=True)
    records = {d.name: stored_record(results / f"{d.name}.json", d) for d in designs}
    pending = [d for d in designs if records[d.name] is None]
    task = task or diagnose_design
    futures = {client.submit(task, d, pure=False, **options): d for d in pending}
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(designs), initial=len(designs) - len(pending),
                   desc="diagnosis study", unit="design")
    try:
        for future in as_completed(futures):
            design = futures[future]
            try:
                record = future.result()
            except Exception as error:  # noqa: BLE001 (a worker lost: recorded, not fatal)
                record = {"name": design.name, "design": design.to_json(),
                          "hidden": design.hidden_label, "curves": len(design.specimens),
                          "error": f"{type(error).__name__}: {error}"}
            write_json(results / f"{design.name}.json", record)
            records[design.name] = json.loads((results / f"{design.name}.json").read_text())
            if bar is not None:
                bar.set_postfix_str(f"{design.hidden_label} -> {record.get('found', '')}")
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    return [records[d.name] for d in designs], len(pending)
