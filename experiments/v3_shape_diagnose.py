"""The V3 kite from the plain model (Breukels' 2011 law unscaled, the model file's trailing
edge) diagnosed on two 0.15 bar cases, ``P1_S`` and ``P1_TL1``, with one candidate, the
trailing edge's rest lengths: a short run of ``jaxtube shape diagnose``'s loop
(:func:`fitting.diagnose_campaign`) on the loaded 2-core machine. The whole diagnosis (five
cases, every built-in candidate) is ``jaxtube shape diagnose
experiments/data/v3_hanging/campaign.toml --out DIR``.

Writes ``experiments/results/v3_shape_diagnose/report.txt`` and ``model.json`` (read by
``jaxtube shape compare|predict --model``).

Usage: ``python -m experiments.v3_shape_diagnose``
"""

import json
import time
from pathlib import Path

import fitting
import jaxtube as jt

ROOT = Path(__file__).resolve().parent
CASES = ["P1_S", "P1_TL1"]


def main() -> None:
    jt.enable_compilation_cache()
    campaign = fitting.read_campaign(ROOT / "data" / "v3_hanging" / "campaign.toml")
    candidate = fitting.shape_effects(campaign)["rest_length.trailing_edge"]
    solver = fitting.CaseSolver(campaign, tangent_values=("bending_scale",) + candidate.values)
    started = time.perf_counter()
    found = fitting.diagnose_campaign(campaign, campaign.model, ("bending_scale",),
                                      [candidate], CASES, solver, log=print)
    seconds = time.perf_counter() - started
    out = ROOT / "results" / "v3_shape_diagnose"
    out.mkdir(parents=True, exist_ok=True)
    (out / "report.txt").write_text(fitting.diagnosis_report(found, CASES, seconds))
    (out / "model.json").write_text(json.dumps(found.final.to_json(), indent=2) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
