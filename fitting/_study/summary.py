"""The diagnosis study's tables from its records (:func:`fitting._study.run.diagnose_design`):
the confusion table, the false-alarm rate on null designs, power against the effect's
signal-to-noise ratio, the "cannot be told apart" statements against what the design can
separate, the final RMSE and the noise estimate against the noise floor, and time; with
the issue's targets (issue 34) beside them. A rate with nothing to count is None (``null``
in JSON), never 0. Each rate held against a target carries its exact (Clopper-Pearson) 95 %
interval: a few dozen designs leave rates uncertain by tens of percent, and whether a target
is met is a statement about the interval, not the point.
"""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
from scipy.stats import beta

#: Signal-to-noise bins of the power table: the effect's largest change of the curves in
#: noise-floor units.
SNR_EDGES = (0.0, 1.0, 3.0, 10.0, 30.0, math.inf)
#: The issue's targets.
FALSE_ALARM_TARGET = 0.05
POWER_TARGET, POWER_SNR = 0.95, 3.0
RMSE_RATIO, RMSE_TARGET = 1.3, 0.95
NOISE_ERROR, NOISE_TARGET = 0.25, 0.95
SECONDS_TARGET, TARGET_CURVES = 60.0, 6


def _rate(hits: int, total: int) -> float | None:
    return hits / total if total else None


def rate_interval(hits: int, total: int, level: float = 0.95) -> list[float] | None:
    """The exact (Clopper & Pearson 1934) interval ``[low, high]`` of a binomial rate from
    ``hits`` of ``total`` at confidence ``level``: the beta quantiles that bound it; None for
    no trials."""
    if not total:
        return None
    tail = (1.0 - level) / 2.0
    low = 0.0 if hits == 0 else float(beta.ppf(tail, hits, total - hits + 1))
    high = 1.0 if hits == total else float(beta.ppf(1.0 - tail, hits + 1, total - hits))
    return [low, high]


def effect_outcomes(records) -> list[dict]:
    """One row per hidden effect of every diagnosed design: ``effect``, ``snr``,
    ``separable``, ``found`` (in the verdict), ``clean`` (no physical effect named that is not
    hidden), ``said_cannot_tell`` (a statement says it cannot be told apart or tested)."""
    rows = []
    for record in records:
        if record.get("error") is not None:
            continue
        hidden = set(record["design"]["hidden"])
        found = set() if record["found"] == "none" else set(record["found"].split("+"))
        for effect in sorted(hidden):
            rows.append({"design": record["name"], "effect": effect,
                         "snr": record["snr"][effect], "separable": record["separable"][effect],
                         "found": effect in found, "clean": found <= hidden,
                         "said_cannot_tell": effect in record["cannot_tell"]})
    return rows


def study_summary(records) -> dict:
    """The study's tables (JSON-ready; module docstring) from its ``records``."""
    done = [r for r in records if r.get("error") is None]
    failed = [r for r in records if r.get("error") is not None]
    confusion = Counter((r["hidden"], r["found"]) for r in done)
    hidden_labels = sorted({r["hidden"] for r in done})
    found_labels = sorted({r["found"] for r in done})
    nulls = [r for r in done if r["hidden"] == "none"]
    false_alarms = sum(r["found"] != "none" for r in nulls)
    outcomes = effect_outcomes(done)
    power = []
    for low, high in zip(SNR_EDGES[:-1], SNR_EDGES[1:]):
        for separable in (True, False):
            rows = [o for o in outcomes if low <= o["snr"] < high and o["separable"] == separable]
            power.append({"snr_low": low, "snr_high": high, "separable": separable,
                          "effects": len(rows),
                          "found": _rate(sum(o["found"] for o in rows), len(rows)),
                          "found_clean": _rate(sum(o["found"] and o["clean"] for o in rows),
                                               len(rows))})
    resolvable = [o for o in outcomes if o["snr"] > POWER_SNR and o["separable"]]
    resolvable_found = sum(o["found"] and o["clean"] for o in resolvable)
    told = {}
    for separable in (True, False):
        rows = [o for o in outcomes if o["separable"] == separable]
        told["separable" if separable else "not_separable"] = {
            "effects": len(rows), "said_cannot_tell": sum(o["said_cannot_tell"] for o in rows),
            "found": sum(o["found"] for o in rows),
            "neither": sum(not o["found"] and not o["said_cannot_tell"] for o in rows)}
    rmse_ratio = np.array([r["final_rmse_N"] / r["noise_floor_N"] for r in done])
    noise_error = np.array([r["noise_N"] / r["noise_floor_N"] - 1.0 for r in done])
    rmse_within = int(np.sum(rmse_ratio <= RMSE_RATIO))
    noise_within = int(np.sum(np.abs(noise_error) <= NOISE_ERROR))
    seconds = np.array([r["seconds"] for r in done])
    target_seconds = np.array([r["seconds"] for r in done
                               if r["curves"] == TARGET_CURVES and r.get("warm")])

    def quantiles(values):
        return ({f"q{int(q * 100):02d}": float(np.quantile(values, q))
                 for q in (0.05, 0.25, 0.5, 0.75, 0.95)} if values.size else {})

    restarted = [r["baseline_restart"] for r in done if r.get("baseline_restart")]
    gains = np.array([r["chi2_gain"] for r in restarted if r["kept"] > 0])
    return {
        "designs": len(records), "diagnosed": len(done), "failed": len(failed),
        "failures": {r["name"]: r["error"] for r in failed},
        "final_not_converged": sum(not r["final_converged"] for r in done),
        "baseline_not_converged": sum(not r["baseline_converged"] for r in done),
        "baseline_restarted": {"designs": len(restarted), "restart_kept": int(gains.size),
                               "chi2_gain_median": (float(np.median(gains)) if gains.size
                                                    else None)},
        "confusion": {"hidden": hidden_labels, "found": found_labels,
                      "counts": [[confusion[h, f] for f in found_labels] for h in hidden_labels]},
        "false_alarm": {"nulls": len(nulls), "false_alarms": false_alarms,
                        "rate": _rate(false_alarms, len(nulls)),
                        "interval_95": rate_interval(false_alarms, len(nulls)),
                        "target": FALSE_ALARM_TARGET},
        "power": power,
        "power_resolvable": {
            "effects": len(resolvable),
            "found_clean": _rate(resolvable_found, len(resolvable)),
            "interval_95": rate_interval(resolvable_found, len(resolvable)),
            "snr_above": POWER_SNR, "target": POWER_TARGET},
        "cannot_tell": told,
        "final_rmse_over_floor": {
            "within": _rate(rmse_within, rmse_ratio.size),
            "interval_95": rate_interval(rmse_within, rmse_ratio.size),
            "ratio": RMSE_RATIO, "target": RMSE_TARGET, **quantiles(rmse_ratio)},
        "noise_estimate_error": {
            "within": _rate(noise_within, noise_error.size),
            "interval_95": rate_interval(noise_within, noise_error.size),
            "error": NOISE_ERROR, "target": NOISE_TARGET, **quantiles(noise_error)},
        "seconds": {"median": float(np.median(seconds)) if seconds.size else None,
                    "median_6_curves_warm": (float(np.median(target_seconds))
                                             if target_seconds.size else None),
                    "designs_6_curves_warm": int(target_seconds.size),
                    "target_6_curves": SECONDS_TARGET, **quantiles(seconds)},
    }


def _percent(value) -> str:
    return "n/a" if value is None else f"{value:.0%}"


def _interval(row: dict) -> str:
    """`` (95 % interval a-b %)`` of a row's ``interval_95``, or nothing without one."""
    interval = row.get("interval_95")
    if interval is None:
        return ""
    return f" (95 % interval {interval[0]:.0%}-{interval[1]:.0%})"


def study_report(summary: dict) -> str:
    """The summary as text: each table with its target and how many designs it rests on."""
    s = summary
    lines = [f"designs: {s['designs']} ({s['diagnosed']} diagnosed, {s['failed']} failed); "
             f"final model not converged in {s['final_not_converged']}, baseline in "
             f"{s['baseline_not_converged']}"]
    restart = s.get("baseline_restarted", {})
    if restart.get("designs"):
        lines.append(
            f"baseline restarted (first fit on its box) in {restart['designs']}: a restart kept "
            f"in {restart['restart_kept']}" + (
                f", chi^2 lower by {restart['chi2_gain_median']:.3g} noise units (median)"
                if restart["chi2_gain_median"] is not None else ""))
    lines.append("")
    confusion = s["confusion"]
    width = max([len(f) for f in confusion["found"]] + [8]) + 2
    lines.append("confusion (rows: hidden; columns: physical effects named)")
    lines.append(f"  {'hidden':<34}" + "".join(f"{f:>{width}}" for f in confusion["found"]))
    for label, counts in zip(confusion["hidden"], confusion["counts"]):
        lines.append(f"  {label:<34}" + "".join(f"{c:>{width}}" for c in counts))
    fa = s["false_alarm"]
    lines += ["", f"false alarms on null designs: {fa['false_alarms']} of {fa['nulls']} = "
                  f"{_percent(fa['rate'])}{_interval(fa)} (target <= {fa['target']:.0%})", "",
              "power: share of hidden effects named, by signal-to-noise (largest change of the "
              "curves in noise-floor units)",
              f"  {'SNR':<12}{'separable':>10}{'effects':>9}{'found':>8}{'found, no other':>17}"]
    for row in s["power"]:
        if row["effects"]:
            span = f"{row['snr_low']:g}-{row['snr_high']:g}"
            lines.append(f"  {span:<12}{'yes' if row['separable'] else 'no':>10}"
                         f"{row['effects']:>9}{_percent(row['found']):>8}"
                         f"{_percent(row['found_clean']):>17}")
    pr = s["power_resolvable"]
    lines.append(f"  SNR > {pr['snr_above']:g} and separable: found with no other physical effect "
                 f"in {_percent(pr['found_clean'])} of {pr['effects']}{_interval(pr)} (target >= "
                 f"{pr['target']:.0%})")
    lines += ["", "'cannot be told apart' against what the design can separate (hidden effects)"]
    for key, row in s["cannot_tell"].items():
        lines.append(f"  {key.replace('_', ' '):<14}: {row['effects']} effects; said cannot be "
                     f"told apart {row['said_cannot_tell']}, found {row['found']}, neither "
                     f"{row['neither']}")
    for key, words, share in (
            ("final_rmse_over_floor", "final RMSE / noise floor", "ratio"),
            ("noise_estimate_error", "noise estimate / floor - 1", "error")):
        row = s[key]
        bound = (f"<= {row['ratio']:g}" if share == "ratio" else f"within {row['error']:.0%}")
        quantile_words = ", ".join(f"{k} {row[k]:+.2f}" if share == "error" else
                                   f"{k} {row[k]:.2f}" for k in row if k.startswith("q"))
        lines += ["", f"{words}: {bound} in {_percent(row['within'])}{_interval(row)} (target >= "
                      f"{row['target']:.0%}); quantiles {quantile_words or 'n/a'}"]
    t = s["seconds"]
    median6 = ("n/a" if t["median_6_curves_warm"] is None
               else f"{t['median_6_curves_warm']:.0f} s")
    median = "n/a" if t["median"] is None else f"{t['median']:.0f} s"
    lines += ["", f"seconds per diagnosis: median {median} (first of a shape in a worker "
                  f"included); warm 6-curve designs median {median6} over "
                  f"{t['designs_6_curves_warm']} (target <= {t['target_6_curves']:g} s)"]
    if s["failures"]:
        lines += ["", "failed designs:"] + [f"  {k}: {v}" for k, v in s["failures"].items()]
    return "\n".join(lines)
