"""Benchmark: the Newton solver's nonmonotone Armijo tests on the ten V3 hanging-test cases.

Every case of ``experiments/data/v3_hanging/campaign.toml`` solved by its route from the
undeformed shape with the diagnosis' model (``results/v3_shape_diagnose/model.json``), once
per ``NewtonKKT.nonmonotone_window`` (1: the monotone Armijo tests), each window in its own
process (a case's compiled program does not depend on the window's value otherwise). Counts
per case the Newton steps, the KKT factorisations (every regularised step and every
second-order correction: one KLU factorisation each on the augmented route, counted by a
host callback in the traced solver) and the warm seconds (median of ``--repeats``), and the
largest distance of each window's equilibria from the first window's [mm].

    python -m experiments.bench_v3_nonmonotone [--windows 1 3 5 8] [--repeats 3]

Writes ``experiments/results/bench_v3_nonmonotone.txt``. Data: experiments/data/v3_hanging
("Structural model data from awegroup/kite_fem (MIT, (c) 2025 Patrick Roeleveld)").
"""

import argparse
import dataclasses
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
CAMPAIGN = ROOT / "data" / "v3_hanging" / "campaign.toml"
MODEL = ROOT / "results" / "v3_shape_diagnose" / "model.json"


def run_window(window: int, repeats: int, out: Path) -> None:
    """Solve every case with ``window`` (this process), write the counts and positions."""
    import jax

    import fitting
    from jaxtube._solver import newton_kkt

    counts = {"steps": 0, "corrections": 0}

    def counted(name, function):
        def wrapper(*args, **kwargs):
            result = function(*args, **kwargs)
            jax.debug.callback(lambda _: counts.__setitem__(name, counts[name] + 1),
                               jax.tree.leaves(result)[0])
            return result
        return wrapper

    newton_kkt.regularised_step = counted("steps", newton_kkt.regularised_step)
    newton_kkt.second_order_correction = counted("corrections",
                                                 newton_kkt.second_order_correction)
    campaign = fitting.read_campaign(CAMPAIGN)
    model = fitting.read_model_file(MODEL, campaign)
    solver = fitting.CaseSolver(campaign)
    solver.solver = dataclasses.replace(solver.solver, nonmonotone_window=window)
    rows, positions = [], {}
    for case in campaign.cases:
        seconds = []
        for _ in range(repeats):
            counts.update(steps=0, corrections=0)
            solved = solver.solve(case, model)
            seconds.append(solved.seconds)
        newton = sum(solved.newton_iterations) + (
            sum(solved.drive["newton_iterations"]) if solved.drive else 0)
        rows.append({"case": case.name, "converged": solved.converged, "newton_steps": newton,
                     "factorisations": counts["steps"] + counts["corrections"],
                     "corrections": counts["corrections"],
                     "seconds": statistics.median(seconds)})
        positions[case.name] = solved.positions
    (out / f"window_{window}.json").write_text(json.dumps(rows))
    np.savez(out / f"window_{window}.npz", **positions)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--windows", type=int, nargs="+", default=[1, 3, 5, 8])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--one-window", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--into", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one_window is not None:
        run_window(args.one_window, args.repeats, Path(args.into))
        return
    lines = [f"V3 hanging test, ten cases from the undeformed shape, {MODEL.name} of the "
             f"diagnosis; {args.repeats} repeats (median seconds); load average "
             f"{os.getloadavg()[0]:.2f}"]
    with tempfile.TemporaryDirectory() as folder:
        for window in args.windows:
            subprocess.run([sys.executable, "-m", "experiments.bench_v3_nonmonotone",
                            "--one-window", str(window), "--repeats", str(args.repeats),
                            "--into", folder], check=True, cwd=ROOT.parent)
        first = np.load(Path(folder) / f"window_{args.windows[0]}.npz")
        for window in args.windows:
            rows = json.loads((Path(folder) / f"window_{window}.json").read_text())
            here = np.load(Path(folder) / f"window_{window}.npz")
            distance = max(float(np.max(np.abs(here[k] - first[k]))) for k in first) * 1e3
            total = {key: sum(r[key] for r in rows)
                     for key in ("newton_steps", "factorisations", "corrections", "seconds")}
            lines.append(
                f"window {window}: Newton steps {total['newton_steps']}, KKT factorisations "
                f"{total['factorisations']} (second-order corrections "
                f"{total['corrections']}), {total['seconds']:.1f} s warm in all, all "
                f"converged {all(r['converged'] for r in rows)}; largest distance from window "
                f"{args.windows[0]}: {distance:.1e} mm")
            lines += [f"  {r['case']}: {r['newton_steps']} steps, {r['factorisations']} "
                      f"factorisations ({r['corrections']} corrections), {r['seconds']:.2f} s"
                      for r in rows]
    text = "\n".join(lines) + f"\nload average at the end {os.getloadavg()[0]:.2f}\n"
    print(text)
    (ROOT / "results" / "bench_v3_nonmonotone.txt").write_text(text)


if __name__ == "__main__":
    main()
