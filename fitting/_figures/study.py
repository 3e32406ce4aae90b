"""Figure of the diagnosis study (:mod:`fitting._study`): power against the effect's
signal-to-noise ratio, the noise estimate's error, the final RMSE against the noise floor,
and seconds per diagnosis. Built without pyplot (no global state)."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from .._study.summary import (
    NOISE_ERROR,
    POWER_SNR,
    RMSE_RATIO,
    SECONDS_TARGET,
    SNR_EDGES,
    effect_outcomes,
)


def study_figure(records, title: str = "diagnosis study") -> Figure:
    """Four panels from the study's records: each hidden effect found (1) or not (0) against
    its signal-to-noise ratio (filled: the design can separate it), with the share found per
    bin; the noise estimate's relative error; the final RMSE over the noise floor; seconds
    per diagnosis against the number of curves (open: the first of its shape in its worker,
    compilation included). Dashed lines: the issue's targets."""
    done = [r for r in records if r.get("error") is None]
    figure = Figure(figsize=(12, 8.5), layout="constrained")
    power, noise, rmse, seconds = figure.subplots(2, 2).ravel()
    outcomes = effect_outcomes(done)
    rng = np.random.default_rng(0)
    effects = sorted({o["effect"] for o in outcomes})
    for k, effect in enumerate(effects):
        rows = [o for o in outcomes if o["effect"] == effect]
        snr = np.array([max(o["snr"], 1e-2) for o in rows])
        hit = np.array([float(o["found"] and o["clean"]) for o in rows])
        jitter = hit + (rng.random(hit.size) - 0.5) * 0.12
        separable = np.array([o["separable"] for o in rows])
        power.scatter(snr[separable], jitter[separable], color=f"C{k}", s=22, label=effect)
        power.scatter(snr[~separable], jitter[~separable], facecolors="none",
                      edgecolors=f"C{k}", s=22)
    centres, shares = [], []
    for low, high in zip(SNR_EDGES[:-1], SNR_EDGES[1:]):
        rows = [o for o in outcomes if low <= o["snr"] < high and o["separable"]]
        if rows:
            centres.append(np.sqrt(max(low, 0.3) * min(high, 100.0)))
            shares.append(np.mean([o["found"] and o["clean"] for o in rows]))
    power.plot(centres, shares, "k-o", ms=4, label="share found (separable)")
    power.axvline(POWER_SNR, color="k", ls="--", lw=0.8)
    power.axhline(0.95, color="0.5", ls=":", lw=0.8)
    power.set_xscale("log")
    power.set_xlim(0.1, max([300.0] + [2 * o["snr"] for o in outcomes]))
    power.set_xlabel("effect signal-to-noise (largest change / noise floor)")
    power.set_ylabel("found, no other effect named")
    power.set_title("power (open: the design cannot separate it)", fontsize=10)
    power.legend(fontsize=7)
    power.grid(alpha=0.3)
    error = np.array([r["noise_N"] / r["noise_floor_N"] - 1.0 for r in done])
    noise.hist(error, bins=20, color="C0")
    for side in (-NOISE_ERROR, NOISE_ERROR):
        noise.axvline(side, color="k", ls="--", lw=0.8)
    noise.set_xlabel("noise estimate / noise floor - 1")
    noise.set_ylabel("designs")
    noise.set_title("noise estimate's error", fontsize=10)
    ratio = np.array([r["final_rmse_N"] / r["noise_floor_N"] for r in done])
    rmse.hist(ratio, bins=20, color="C2")
    rmse.axvline(RMSE_RATIO, color="k", ls="--", lw=0.8)
    rmse.set_xlabel("final RMSE / noise floor")
    rmse.set_ylabel("designs")
    rmse.set_title("final error", fontsize=10)
    curves = np.array([r["curves"] for r in done])
    warm = np.array([bool(r.get("warm")) for r in done])
    spent = np.array([r["seconds"] for r in done])
    shifted = curves + (rng.random(curves.size) - 0.5) * 0.3
    seconds.scatter(shifted[warm], spent[warm], s=16, color="C3", label="warm")
    seconds.scatter(shifted[~warm], spent[~warm], s=16, facecolors="none", edgecolors="C3",
                    label="first of its shape (compiles)")
    seconds.legend(fontsize=7)
    seconds.axhline(SECONDS_TARGET, color="k", ls="--", lw=0.8)
    seconds.set_xlabel("curves")
    seconds.set_ylabel("seconds per diagnosis")
    seconds.set_title("time", fontsize=10)
    seconds.grid(alpha=0.3)
    figure.suptitle(f"{title}: {len(done)} designs diagnosed", fontsize=11)
    return figure
