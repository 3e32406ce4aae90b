"""The V3 kite from the plain model (Breukels' 2011 law unscaled, the model file's trailing
edge) diagnosed on the five 0.15 bar cases with every built-in candidate
(``jaxtube shape diagnose experiments/data/v3_hanging/campaign.toml``), then the model it
ends with scored on those cases with the peers' metric (``jaxtube shape compare``) and the
five 0.25 bar cases predicted with it (``jaxtube shape predict``: their markers are held
out; scored outside the repository).

Writes ``experiments/results/v3_shape_diagnose/``: the diagnosis' files (``report.txt``,
``diagnosis.json``, ``model.json``, ``cases.csv``, figures), ``compare_cases.csv`` (the
peers' metric per case) and ``predictions/<case>/`` (``positions.csv``, ``summary.json``).

Usage: ``python -m experiments.v3_shape_diagnose``
"""

import shutil
import tempfile
from pathlib import Path

from fitting._cli.main import main as jaxtube

ROOT = Path(__file__).resolve().parent
CAMPAIGN = ROOT / "data" / "v3_hanging" / "campaign.toml"
OUT = ROOT / "results" / "v3_shape_diagnose"
CALIBRATION = ["P1_S", "P1_PL1", "P1_PL2", "P1_TL1", "P1_TL2"]
HELD_OUT = ["P2_S", "P2_PL1", "P2_PL2", "P2_TL1", "P2_TL2"]


def main() -> int:
    code = jaxtube(["shape", "diagnose", str(CAMPAIGN), "--out", str(OUT)])
    model = str(OUT / "model.json")
    with tempfile.TemporaryDirectory() as folder:
        code = max(code, jaxtube(["shape", "compare", str(CAMPAIGN), "--model", model,
                                  "--cases", *CALIBRATION, "--no-figures", "--out",
                                  folder]))
        shutil.copy(Path(folder) / "cases.csv", OUT / "compare_cases.csv")
    return max(code, jaxtube(["shape", "predict", str(CAMPAIGN), "--model", model,
                              "--cases", *HELD_OUT, "--out", str(OUT / "predictions")]))


if __name__ == "__main__":
    raise SystemExit(main())
