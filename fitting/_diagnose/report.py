"""The diagnosis in words: the rankings, where the baseline fails, the before/after table
and the verdict (what ``jaxtube diagnose`` prints and writes to ``report.txt``)."""

from __future__ import annotations

from .._data.units import MM_PER_M


def _ranking_lines(rows) -> list[str]:
    lines = [f"  {'candidate':<20}{'score S':>10}{'p':>10}{'LR':>10}{'p (LR)':>10}"
             f"{'RMSE [N]':>10}{'ΔBIC':>10}{'CV RMSE [N]':>13}{'unabsorbed':>12}  significant"
             " (the likelihood ratio decides; the score only orders the refits)"]
    for row in rows:
        lines.append(f"  {row.effect:<20}{row.score_statistic:>10.3g}{row.score_p_value:>10.2g}"
                     f"{row.lr_statistic:>10.3g}{row.lr_p_value:>10.2g}"
                     f"{row.rmse_N:>10.4g}{row.delta_bic:>10.1f}{row.cv_rmse_N:>13.4g}"
                     f"{row.unabsorbed_share:>12.1%}  "
                     + ("yes" if row.significant else "no: " + "; ".join(row.reasons)))
    return lines


def convergence_lines(diagnosis) -> list[str]:
    """Words on fits that did not converge: the baseline (expected when it misses an effect;
    the verdict rests on the final model) and the final model (then the verdict is not to be
    trusted: ``jaxtube diagnose`` exits 1)."""
    lines = []
    baseline, final = diagnosis.baseline.convergence, diagnosis.final.convergence
    if not baseline.converged and diagnosis.steps:
        lines.append(f"baseline fit did not converge ({baseline.message}): expected of a model "
                     "that misses an effect; the verdict rests on the final model")
    if not final.converged:
        lines.append(f"FINAL MODEL DID NOT CONVERGE ({final.message}): the verdict and its "
                     "numbers are not to be trusted")
    return lines


def diagnosis_report(diagnosis) -> str:
    """The before/after table, the rankings, where the baseline fails and the verdict."""
    lines = []
    base = diagnosis.baseline_comparison
    estimate = diagnosis.noise_estimate
    source = "given" if estimate is None else (
        f"estimated from the data, model-free: +- {estimate.standard_error_N:.2g} N")
    lines.append(f"noise: {diagnosis.noise:.4g} N ({source})")
    lines += convergence_lines(diagnosis)
    lines.append("(unabsorbed: the share of a candidate's effect on the curves that refitting "
                 "the current model's parameters cannot reproduce)")
    lines.append("")
    lines.append("baseline (paper scaling, no effect): " + base.verdict.words)
    worst = base.worst_groups(3)
    lines.append("  worst groups: " + "; ".join(f"{g.quantity} {g.label}: RMSE {g.rmse_N:.3g} "
                                               f"N, bias {g.bias_N:+.3g} N" for g in worst))
    if diagnosis.baseline_restart is not None:
        lines.append("  restarted: " + diagnosis.baseline_restart.words())
    for k, step in enumerate(diagnosis.steps):
        lines.append("")
        if step.refinement:
            layout = ",".join(str(n) for n in step.fit.problem.scaling.pivots_per_regime)
            lines.append(f"step {k + 1}: no candidate is significant and the residuals are "
                         f"still systematic -> refine the law's pivots to ({layout})")
        else:
            lines.append(f"step {k + 1}: candidates against the current model, best first "
                         f"-> add {step.added}")
        lines += _ranking_lines(step.candidates)
        lines += ["  " + words for words in step.backward]
    if diagnosis.final_candidates:
        lines.append("")
        lines.append(f"final ranking ({diagnosis.stop_reason}):")
        lines += _ranking_lines(diagnosis.final_candidates)
    lines.append("")
    lines.append(f"{'model':<34}{'RMSE [N]':>10}{'max |err| [N]':>15}{'bias [N]':>10}"
                 f"{'CV RMSE [N]':>13}  residuals")
    models = [("baseline", diagnosis.baseline_comparison, diagnosis.baseline_cv_rmse_N)]
    for k, step in enumerate(diagnosis.steps):
        label = "+ " + " + ".join(step.in_model) if step.in_model else "baseline"
        if step.refinement or any(s.refinement for s in diagnosis.steps[:k]):
            label += ", pivots " + ",".join(
                str(n) for n in step.fit.problem.scaling.pivots_per_regime)
        models.append((label, step.comparison, step.cv_rmse_N))
    for label, comparison, cv in models:
        lines.append(f"{label:<34}{comparison.rmse_N:>10.4g}{comparison.max_error_N:>15.4g}"
                     f"{comparison.bias_N:>10.3g}{cv:>13.4g}  "
                     + ("systematic" if comparison.verdict.systematic else "noise"))
    lines.append(f"{'noise':<34}{diagnosis.noise:>10.4g}")
    lines.append("")
    lines.append(f"{'curve':<18}{'p [bar]':>8}{'r [mm]':>8}{'L [m]':>7}{'baseline':>10}"
                 f"{'final':>9}  RMSE [N]")
    for first, last in zip(base.curves, diagnosis.final_comparison.curves):
        lines.append(f"{first['curve']:<18}{first['pressure_bar']:>8.3g}"
                     f"{first['radius_m'] * MM_PER_M:>8.3g}{first['length_m']:>7.3g}"
                     f"{first['rmse_N']:>10.4g}{last['rmse_N']:>9.4g}")
    lines.append("")
    lines.append("verdict: " + (", ".join(diagnosis.verdict) or "nothing is missing"))
    for sentence in diagnosis.statements:
        lines.append("  - " + sentence)
    return "\n".join(lines)
