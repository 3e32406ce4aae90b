"""The diagnosis' verdict in words: which effects are missing and by which rule, near-ties,
removals and swaps, improvements that were not added and why, implausible sizes, and whether
the noise estimate agrees with the final model's scatter."""

from __future__ import annotations

import math

from .._calibrate.noise import NoiseEstimate
from .._calibrate.result import FitResult
from .score import dispersion, point_count
from .separation import _separation_advice, _spread_words

#: Two significant candidates whose BIC drops differ by less than this explain the data
#: about equally well ("very strong" evidence starts at 10: Kass & Raftery 1995).
CLOSE_BIC = 10.0
#: The final model's residual scatter and the noise estimate disagree when they differ by
#: more than this many standard errors (of the estimate and of the scatter together).
NOISE_DISAGREEMENT_SE = 3.0


def noise_words(noise: float, estimate: NoiseEstimate | None, final: FitResult) -> str:
    """The noise (given, or estimated with its standard error), and whether the final
    model's residual scatter ``sigma sqrt(chi^2 / dof)`` agrees with it (standard error of
    the scatter ``scatter / sqrt(2 dof)``, of a chi distribution for large ``dof``)."""
    dof = max(point_count(final) - len(final.problem.free_index), 1)
    scatter = noise * math.sqrt(dispersion(final))
    head = (f"Noise {estimate.words()}" if estimate is not None else
            f"Noise {noise:.3g} N (given)")
    se_estimate = estimate.standard_error_N if estimate is not None else 0.0
    se_scatter = scatter / math.sqrt(2 * dof)
    gap = (scatter - noise) / max(math.hypot(se_estimate, se_scatter), 1e-300)
    if abs(gap) <= NOISE_DISAGREEMENT_SE:
        return (f"{head}; the final model's residual scatter, {scatter:.3g} N, agrees with "
                f"it ({gap:+.1f} standard errors).")
    side = ("larger: the model still misses something, or the noise is underestimated"
            if gap > 0 else "smaller: the noise is overestimated (or the model fits the noise)")
    return (f"{head}; the final model's residual scatter, {scatter:.3g} N, disagrees with it: "
            f"{abs(gap):.1f} standard errors {side}.")


def verdict_words(baseline, baseline_comparison, steps, in_model, final_comparison, ranking,
                  candidates) -> list[str]:
    """Sentences of the verdict: per step the rule that decided, the backward step's
    removals and swaps, near-ties, the final error, and candidates that improve the fit but
    were not added (with why)."""
    noise = baseline.noise
    by_name = {c.name: c for c in candidates}
    words = []
    if not steps:
        if baseline_comparison.verdict.systematic:
            words.append(
                f"Nothing among the candidates is missing, yet the residuals are systematic "
                f"(RMSE {baseline.rmse:.3g} N, noise {noise:.3g} N): the missing physics is "
                "not among the candidates. Write it as an effect (see the README) and pass it "
                "with --effect FILE.py:Class.")
        else:
            words.append(
                f"Nothing is missing: the model explains the data to within the noise (RMSE "
                f"{baseline.rmse:.3g} N, noise {noise:.3g} N) and no candidate is significant.")
    else:
        final = steps[-1].fit
        for step in steps:
            if step.refinement:  # its words are among the statements after the verdict's
                continue
            row = step.candidates[0]
            values = ", ".join(f"{k.split('.', 1)[1]} = {v:.4g}" for k, v in row.estimates.items())
            cv_words = (f"cross-validated error {step.current_cv_rmse_N:.3g} -> "
                        f"{row.cv_rmse_N:.3g} N" if math.isfinite(row.cv_rmse_N)
                        and math.isfinite(step.current_cv_rmse_N)
                        else "cross-validation left out (no valid fold design)")
            words.append(
                f"Missing: {step.added} ({values}): likelihood-ratio test on the refit LR = "
                f"{row.lr_statistic:.3g}"
                + (f" in units of the residual scatter (c = {row.dispersion:.3g})"
                   if row.dispersion > 1.0 else "")
                + f" (p = {row.lr_p_value:.2g}; decides), ΔBIC "
                f"{row.delta_bic:.1f}, {cv_words}; score test at the null S = "
                f"{row.score_statistic:.3g} (p = {row.score_p_value:.2g}; orders the refits "
                "only).")
            words += list(step.backward)
            for rival in step.candidates[1:]:
                if rival.significant and rival.delta_bic - row.delta_bic < CLOSE_BIC:
                    pair = [by_name[step.added], by_name[rival.effect]]
                    quantities = tuple(dict.fromkeys(q for e in pair for q in e.separated_by))
                    _, fixed = _spread_words(baseline.problem.data, quantities)
                    words.append(
                        f"{step.added} and {rival.effect} can barely be told apart with this "
                        f"data: either alone explains it (ΔBIC {row.delta_bic:.1f} and "
                        f"{rival.delta_bic:.1f}, a difference under {CLOSE_BIC:g}; "
                        f"cross-validated error {row.cv_rmse_N:.3g} and {rival.cv_rmse_N:.3g} "
                        f"N). {step.added} is kept for its lower BIC; check that its value is "
                        f"plausible. " + _separation_advice(pair, fixed))
        model = ", ".join(in_model) or "no effect"
        if any(step.refinement for step in steps):
            model += " and the refined pivots"
        words.append(
            f"With {model} the RMSE falls from {baseline.rmse:.3g} "
            f"N to {final.rmse:.3g} N (noise {noise:.3g} N). "
            + ("The remaining residuals are noise." if not final_comparison.verdict.systematic
               else "The remaining residuals are still systematic: "
               + final_comparison.verdict.words))
    close = [row for row in ranking if not row.significant and (
        row.score_p_value < 0.01 or row.lr_p_value < 0.01)]
    for row in close:
        words.append(f"{row.effect} improves the fit but is not added: "
                     + "; ".join(row.reasons) + ".")
    for step in steps:  # implausible rivals that would have won a step
        for row in step.candidates if not step.refinement else ():
            if not row.plausible and row.delta_bic < step.candidates[0].delta_bic:
                words.append(f"At the step that added {step.added}: " + "; ".join(
                    r for r in row.reasons if "explains it only at" in r) + ".")
    return words
