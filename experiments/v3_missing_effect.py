"""The product's loop on the V3 kite's centre-load cases (issue 15): where the calibrated
model fails, which effect is missing, and what adding it does to the error.

The baseline model (Breukels' 2011 bending law x s on every tube, s = 0.378 fitted to case 1
alone, torsion unscaled: ``results/v3_calibration_moment.json``; the calibration the V3 script
used until this experiment chose the "softer, not weaker" form) predicts case 2 (9.7 kg on
leading-edge node 29) at 130 mm and case 3 (25.2 kg) at 260 mm (``v3_hanging_test.py score``).
Case 3's twelve measured lengths say where: the trailing-edge distance ``Le`` between the two
central struts is 0.92 m measured and 0.27 m in the model, so the model folds the kite about
its centre (the leading edge kinks under the load) where the real kite does not. Three
candidates, each one number fitted to one case (the others then scored as predictions):

- ``le_bending``: the leading edge's bending law gets its own factor ``b`` on top of the
  calibrated ``s`` (the struts keep ``s``). Physical reading: the case-1 factor is a
  whole-kite average; the leading edge (the largest tube, loaded in a way case 1 hardly
  tests) is stiffer or stronger than that average.
- ``le_torsion``: the leading edge's torsion law (Breukels 2011, unscaled so far) times
  ``t``. Physical reading: the centre load twists the leading edge where the struts join it.
- ``strength_kept``: not an added number but the calibration's form. ``s`` scales the 2011
  curve's moments, so the calibrated tubes are also 2.6 times weaker: they wrinkle and
  collapse at 0.38 of the moments that pressure and radius set. ``CurvatureScaledLaw``
  instead stretches the curve along the curvature axis: the stiffness x ``c``, the moments
  (the collapse plateau) kept. ``c`` is refitted to case 1 (the calibration's own data, as
  ``s`` was); cases 2-5 are then predictions.

Each fit: bounded Brent on ``log`` of the factor (``scipy.optimize.minimize_scalar``), every
evaluation a converged hang (the centre load reached by ``jaxtube.drive_to_dead_load``) and
a fresh registration. One compiled program per load type serves every case and factor (the
factors are traced leaves of the parameters).

    python experiments/v3_missing_effect.py [--effects le_bending le_torsion]

Writes ``experiments/results/v3_missing_effect.{txt,json}``. Data and licences: see
``v3_hanging_test.py``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import _v3_model as v3  # noqa: E402
from _v3_kite_fem import v3_tube_surfaces  # noqa: E402

import fitting  # noqa: E402
import jaxtube as jt  # noqa: E402

LEADING_EDGE = -1  # the leading edge is the imported kite's last tube ("beams_1_57")
EFFECTS = ("le_bending", "le_torsion", "strength_kept")
FIT_CASE = {"le_bending": 2, "le_torsion": 2, "strength_kept": 1}
FACTOR_INDEX = {"le_bending": 1, "le_torsion": 2, "strength_kept": 0}
BOUNDS = (0.1, 10.0)  # search interval of each factor
# The baseline: Breukels 2011 x s (moments) fitted to case 1 by `v3_hanging_test.py calibrate
# --law-form moment` (s = 0.3784); the committed calibration is the form this script chose.
MOMENT_CALIBRATION = v3.RESULTS / "v3_calibration_moment.json"


def import_case(case: int, family: str = "moment"):
    """The case's imported kite with every tube's torsion law as a ScaledLaw (factor 1), so
    the leading edge's torsion factor is a traced leaf; bending law Breukels 2011 with its
    moments scaled (``family`` "moment", :class:`jaxtube.ScaledLaw`) or stretched along the
    curvature axis ("curvature", :class:`jaxtube.CurvatureScaledLaw`)."""
    pressure, centre, tip, _ = v3.CASES[case]
    bending = None
    if family == "curvature":
        bending = jt.CurvatureScaledLaw(jt.EmpiricalBendingLaw2011(), 1.0)
    imported = jt.import_kite_fem(v3.MODEL, pressure_bar=pressure, bending_law=bending,
                                  bending_scale=1.0 if family == "moment" else None,
                                  torsion_law=jt.ScaledLaw(jt.EmpiricalTorsionLaw2011(), 1.0),
                                  centre_load_kg=centre, tip_load_kg=tip)
    if imported.tube_names[LEADING_EDGE] != "beams_1_57":
        raise RuntimeError(f"expected the leading edge 'beams_1_57' last, got "
                           f"{imported.tube_names}")
    return imported


def with_factors(params, scale, le_bending, le_torsion):
    """Every tube's bending law factor ``scale`` (a moment or a curvature factor, by the
    law), the leading edge's ``scale * le_bending``, its torsion law x ``le_torsion`` (all
    traced)."""
    laws = [eqx.tree_at(lambda law: law.factor, law, scale) for law in params.bending_laws]
    laws[LEADING_EDGE] = eqx.tree_at(lambda law: law.factor, laws[LEADING_EDGE],
                                     scale * le_bending)
    torsion = list(params.torsion_laws)
    torsion[LEADING_EDGE] = eqx.tree_at(lambda law: law.factor, torsion[LEADING_EDGE],
                                        le_torsion)
    return eqx.tree_at(lambda p: (p.bending_laws, p.torsion_laws), params,
                       (tuple(laws), tuple(torsion)))


class Programs:
    """One compiled program per law family and load type: ``(params, factors [3]) ->
    result`` (see ``v3_hanging_test.case_equilibrium``)."""

    compiled: dict = {}
    compile_seconds: dict = {}

    @classmethod
    def solve(cls, imported, family, centre_load_kg, factors):
        key = (family, "centre" if centre_load_kg > 0 else "hang")
        factors = jnp.asarray(factors, dtype=float)
        if key not in cls.compiled:
            structure = imported.structure
            if key[1] == "hang":
                def run(params, f):
                    return jt.hang_kite(structure, with_factors(params, *f), solver=v3.SOLVER,
                                        load_factors=v3.ONE_STAGE)
            else:
                centre = int(imported.node_index[v3.CENTRE_NODE])

                def run(params, f):
                    return v3.centre_load_hang(structure, centre, with_factors(params, *f))
            started = time.perf_counter()
            cls.compiled[key] = jax.jit(run).lower(imported.params, factors).compile()
            cls.compile_seconds["/".join(key)] = time.perf_counter() - started
        return cls.compiled[key](imported.params, factors)


_IMPORTED: dict = {}


def evaluate(case: int, factors, family: str = "moment") -> dict:
    """Hang ``case`` at ``factors`` ``(s, le_bending, le_torsion)`` and score it."""
    if (case, family) not in _IMPORTED:
        _IMPORTED[case, family] = import_case(case, family)
    imported = _IMPORTED[case, family]
    started = time.perf_counter()
    result = jax.block_until_ready(Programs.solve(imported, family, v3.CASES[case][1],
                                                  factors))
    seconds = time.perf_counter() - started
    solution, _, driven = v3.case_equilibrium(result)
    converged = bool(np.asarray(solution.converged)[-1])
    positions = imported.kite_positions(np.asarray(solution.node_position)[-1])
    out = {"case": case, "factors": [float(f) for f in factors], "converged": converged,
           "seconds": round(seconds, 2),
           "drive_reached": None if driven is None else bool(driven.reached)}
    if converged:
        found = fitting.score_shape(v3_tube_surfaces(positions), v3.markers_of(case))
        lengths = v3.measured_lengths(positions)
        measured = v3.read_measured_lengths()[case]
        regime = np.asarray(solution.joint_regime)[-1]
        out.update(rms_mm=found.rms_mm, group_rms_mm=found.group_rms_mm,
                   length_mean_relative_error=float(np.mean(np.abs(lengths - measured)
                                                            / measured)),
                   Le_m=[float(lengths[4]), float(measured[4])],
                   collapsed_joints=int(np.sum(regime == 2)),
                   wrinkled_joints=int(np.sum(regime == 1)))
    return out


def family_of(effect: str) -> str:
    return "curvature" if effect == "strength_kept" else "moment"


def fit(effect: str, scale: float) -> dict:
    """Bounded Brent on log of the effect's factor (``fitting.bounded_search``), the RMS of
    its fit case (``FIT_CASE``); the minimum checked on both sides (as the calibration)."""
    index, case, family = FACTOR_INDEX[effect], FIT_CASE[effect], family_of(effect)
    history = []

    def factors_at(log_factor):
        f = [scale, 1.0, 1.0]
        f[index] = float(np.exp(log_factor))
        return f

    def objective(log_factor):
        row = evaluate(case, factors_at(log_factor), family)
        history.append(row)
        said = f"{row['rms_mm']:.1f} mm" if row["converged"] else "NOT CONVERGED"
        print(f"  {effect} = {np.exp(log_factor):.4f}: case {case} {said} ({row['seconds']} s)",
              file=sys.stderr, flush=True)
        return row["rms_mm"] if row["converged"] else None

    found = fitting.bounded_search(objective, (np.log(BOUNDS[0]), np.log(BOUNDS[1])),
                                   xatol=0.01, max_evaluations=30)
    if found.x is None:
        raise SystemExit(f"error: fitting {effect}: {found.message}")
    return {"effect": effect, "family": family, "fitted_to_case": case,
            "factor": float(np.exp(found.x)), "fit_case_rms_mm": found.value,
            "converged": found.converged, "at_bound": found.at_bound, "message": found.message,
            "evaluations": found.evaluations,
            "rms_mm_at_log_minus_plus": list(found.value_minus_plus),
            "factors": factors_at(found.x), "history": history}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--effects", nargs="+", choices=EFFECTS, default=list(EFFECTS))
    parser.add_argument("--out", default=str(v3.RESULTS))
    args = parser.parse_args(argv)
    baseline = v3.load_calibration(MOMENT_CALIBRATION)
    if baseline["law_form"] != "moment":
        raise SystemExit(f"error: {MOMENT_CALIBRATION}: expected the moment-form calibration")
    scale = float(baseline["bending_scale"])
    started = time.perf_counter()
    models = {"calibrated (none)": ("moment", [scale, 1.0, 1.0])}
    fits = {}
    for effect in args.effects:
        print(f"fitting {effect} on case {FIT_CASE[effect]}", file=sys.stderr, flush=True)
        fits[effect] = fit(effect, scale)
        models[f"+ {effect}"] = (family_of(effect), fits[effect]["factors"])
    cases = tuple(v3.CASES)
    table = {}
    for name, (family, factors) in models.items():
        table[name] = {case: evaluate(case, factors, family) for case in cases}
        print(f"{name}: " + ", ".join(
            f"case {c} {r.get('rms_mm', float('nan')):.1f} mm" for c, r in table[name].items()),
            file=sys.stderr, flush=True)
    lines = [
        f"V3 hanging test: candidate missing effects (bending scale s = {scale:.4f} fitted to "
        "case 1); each effect's number fitted to the case marked *, the others predicted",
        "RMS [mm] (peers' metric); Le: trailing-edge distance between the central struts "
        "[m], model / measured; joints: collapsed / wrinkled in case 3",
        f"{'model':<22} {'factor':>7} " + " ".join(f"{f'case {c}':>7}" for c in cases)
        + f" {'2-3 mean':>8} {'Le case 3':>13} {'joints':>7} conv"]
    for name, rows in table.items():
        effect = name[2:] if name.startswith("+ ") else None
        factor = "-" if effect is None else f"{fits[effect]['factor']:.3f}"
        fitted = 1 if effect is None else FIT_CASE[effect]
        rms = {c: rows[c].get("rms_mm", float("nan")) for c in cases}
        le = rows[3].get("Le_m", [float("nan")] * 2)
        lines.append(
            f"{name:<22} {factor:>7} "
            + " ".join(f"{rms[c]:6.1f}{'*' if c == fitted else ' '}" for c in cases)
            + f" {(rms[2] + rms[3]) / 2:8.1f} {le[0]:6.2f} / {le[1]:4.2f} "
            f"{rows[3].get('collapsed_joints', -1):>3}/{rows[3].get('wrinkled_joints', -1):<3} "
            f"{all(r['converged'] for r in rows.values())}")
    lines.append("targets: case 1 <= 95, cases 2-3 mean <= 150, case 4 <= 110, case 5 <= 79; "
                 "peers (Billow x 0.36 / kite_fem): " + ", ".join(
                     f"case {c} {v[1]}/{v[2]}" for c, v in v3.PEERS.items()))
    for effect, found in fits.items():
        lines.append(f"fit {effect} ({found['family']} law) on case {found['fitted_to_case']}: "
                     f"factor {found['factor']:.4f}, {found['fit_case_rms_mm']:.1f} mm, "
                     f"converged {found['converged']} ({found['message']}; at a bound "
                     f"{found['at_bound']}; {found['evaluations']} evaluations)")
    load = os.getloadavg()
    lines.append(f"{time.perf_counter() - started:.0f} s in all, compile "
                 f"{ {k: round(v) for k, v in Programs.compile_seconds.items()} } s; load "
                 f"average {load[0]:.1f} on 2 cores")
    text = "\n".join(lines) + "\n"
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "v3_missing_effect.txt").write_text(text)
    (out / "v3_missing_effect.json").write_text(json.dumps(
        {"bending_scale": scale, "fits": fits,
         "models": {n: {"family": f, "factors": x} for n, (f, x) in models.items()},
         "cases": {n: {str(c): r for c, r in rows.items()} for n, rows in table.items()}},
        indent=2) + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
