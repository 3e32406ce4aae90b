"""A shape diagnosis in words (``report.txt``) and its ranking as a figure (``ranking.png``)."""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure

from .diagnose import ShapeDiagnosis


def diagnosis_report(found: ShapeDiagnosis, cases, seconds: float) -> str:
    """The report: verdict, the baseline and final fits, each step's ranking, and what the
    cases cannot separate."""
    lines = [f"verdict: {found.verdict}", ""]
    for title, fit in (("baseline", found.baseline), ("final model", found.final)):
        lines.append(f"{title} (converged {fit.converged}: {fit.message}):")
        lines += [f"  {name} = {value:.4g} +- {error:.2g}"
                  for name, value, error in zip(fit.names, fit.values, fit.standard_errors)]
    lines += ["", f"{'case':>10} {'start mm':>9} {'baseline mm':>11} {'final mm':>9}"]
    lines += [f"{c:>10} {found.baseline.rms_mm_before[c]:9.1f} "
              f"{found.baseline.rms_mm_after[c]:11.1f} {found.final.rms_mm_after[c]:9.1f}"
              for c in cases]
    for k, (current, ranking) in enumerate(found.steps):
        mean = math.sqrt(np.mean(np.square(list(current.values()))))
        lines += ["", f"step {k + 1}: held-out RMS of the current model {mean:.1f} mm "
                      "(root mean square over left-out cases)",
                  f"  {'effect':<28} {'gain mm^2':>10} {'BIC fall':>9} {'p':>9}  verdict"]
        for entry in ranking:
            words = "passes" if not entry.reasons else "; ".join(entry.reasons)
            lines.append(f"  {entry.effect.name:<28} {entry.held_out_gain_mm2:10.1f} "
                         f"{entry.bic_fall:9.1f} {entry.p_value:9.2g}  {words}")
    if found.unseparated:
        lines += ["", "what the cases cannot separate or determine:"]
        lines += [f"  {statement}" for statement in found.unseparated]
    lines += ["", f"{seconds:.0f} s (including compilation)"]
    return "\n".join(lines) + "\n"


def ranking_figure(found: ShapeDiagnosis, path) -> None:
    """Each step's candidates by held-out gain [mm²] (passing ones filled)."""
    steps = found.steps
    figure = Figure(figsize=(7, 1.2 + 0.35 * sum(len(r) for _, r in steps) + 0.4 * len(steps)))
    axes = figure.add_subplot()
    labels, y = [], 0
    for k, (_, ranking) in enumerate(steps):
        for entry in ranking:
            gain = entry.held_out_gain_mm2 if math.isfinite(entry.held_out_gain_mm2) else 0.0
            axes.barh(-y, gain, color="C0" if not entry.reasons else "none",
                      edgecolor="C0")
            labels.append(f"step {k + 1}: {entry.effect.name}")
            y += 1
    axes.set_yticks(-np.arange(y), labels)
    axes.axvline(0.0, color="k", linewidth=0.8)
    axes.set_xlabel("held-out gain [mm²] (filled: passes every test)")
    figure.tight_layout()
    figure.savefig(path, dpi=120)
