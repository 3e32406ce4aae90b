"""What the data cannot test or tell apart: candidates that change nothing here, candidates
the current model's parameters absorb, and pairs that change the curves alike; with the data
that would separate them (the sentences of :func:`fitting.diagnose`)."""

from __future__ import annotations

import numpy as np

from .._calibrate.result import FitResult
from .._data import MeasuredData
from .compare import SPECIMEN_UNITS
from .score import _share, absorbed_free_effects, canonical_correlation

#: Below this share of its effect left unabsorbed by a refit of the current model, a
#: candidate cannot be told apart from the current model (:mod:`fitting._diagnose.ranking`).
ABSORBED_SHARE = 0.05
CONFOUNDED_CORRELATION = 0.95
PLURALS = {"pressure": "pressures", "radius": "radii", "length": "lengths"}
#: The data vary a specimen quantity when its largest value exceeds its smallest by more
#: than this ratio.
VARIED_RATIO = 1.2


def _effect_values(result: FitResult) -> dict:
    """Values of the freed effect parameters of ``result``."""
    free = set(result.problem.free_names) - set(result.problem.scaling.names())
    return {name: float(result.vector[i]) for i, name in enumerate(result.problem.names)
            if name in free}



# --------------------------------------------------------------------------------------------
# "Cannot be told apart"
# --------------------------------------------------------------------------------------------


def _changes_curves(effect, jacobian) -> bool:
    """Whether a typical-size value of the effect's parameters changes the model's curves at
    all (by more than 1e-6 noise standard deviations)."""
    typical = np.array([p.typical for p in effect.parameters])
    return bool(np.max(np.abs(jacobian * typical[None, :])) > 1e-6)


def _spread_words(data: MeasuredData, quantities) -> tuple[list[str], list[str]]:
    """(quantities the data vary, sentences on those they do not)."""
    varied, fixed = [], []
    for quantity in quantities:
        values = np.unique([getattr(curve, quantity) for curve in data])
        unit, factor = SPECIMEN_UNITS[quantity]
        if values.size > 1 and values.max() / values.min() > VARIED_RATIO:
            varied.append(quantity)
        elif values.size > 1:
            fixed.append(f"the data's {PLURALS[quantity]} differ by "
                         f"{(VARIED_RATIO - 1) * 100:.0f} % or less "
                         f"({values.min() * factor:.3g}-{values.max() * factor:.3g} {unit})")
        else:
            fixed.append(f"the data have a single {quantity} ({values[0] * factor:.3g} {unit})")
    return varied, fixed


def separation_statements(current: FitResult, candidates, ranking) -> list[str]:
    """Sentences on candidates this data cannot test (they change nothing), cannot tell
    apart from the current model (its parameters absorb their effect: with the smallest size
    that would still be detected), and pairs that change the curves alike (among candidates
    whose score test or refit says they matter)."""
    by_name = {c.name: c for c in candidates}
    rows = {row.effect: row for row in ranking}
    effects = absorbed_free_effects(current, candidates)
    untestable = {c.name for c in candidates if not _changes_curves(c, effects[c.name][1])}
    relevant = [name for name, row in rows.items() if name not in untestable
                and (row.score_p_value < 0.01 or row.delta_bic < 0)]
    data = current.problem.data
    words = []
    for effect in candidates:
        if effect.name in untestable:
            _, fixed = _spread_words(data, effect.separated_by)
            words.append(f"{effect.name} cannot be tested with this data: it does not change "
                         "the model's curves here. " + _separation_advice([effect], fixed))
    for name in [c.name for c in candidates if c.name not in untestable and c.name in rows]:
        residual_part, whole = effects[name]
        share = _share(residual_part, whole)
        if share < ABSORBED_SHARE:
            effect = by_name[name]
            _, fixed = _spread_words(data, effect.separated_by)
            words.append(
                f"{name} cannot be told apart from the current model with this data: refitting "
                f"its parameters ({_model_words(current)}) reproduces {1 - share:.1%} of "
                f"{name}'s effect on the curves, so its size cannot be read from them. "
                + _separation_advice([effect], fixed))
    for i, a in enumerate(relevant):
        for b in relevant[i + 1:]:
            correlation = canonical_correlation(effects[a][0], effects[b][0])
            if correlation > CONFOUNDED_CORRELATION:
                pair = [by_name[a], by_name[b]]
                quantities = tuple(dict.fromkeys(q for e in pair for q in e.separated_by))
                _, fixed = _spread_words(data, quantities)
                words.append(
                    f"{a} and {b} cannot be told apart with this data: once the pivots are "
                    f"refitted they change the curves in the same way (canonical correlation "
                    f"{correlation:.3f}); ΔBIC {rows[a].delta_bic:.1f} and "
                    f"{rows[b].delta_bic:.1f}. " + _separation_advice(pair, fixed))
    return words


def _model_words(result: FitResult) -> str:
    effects = sorted({name.split(".")[0] for name in _effect_values(result)})
    return "the bending law's pivots" + "".join(f", {e}" for e in effects)


def _separation_advice(effects, fixed) -> str:
    quantities = tuple(dict.fromkeys(q for e in effects for q in e.separated_by))
    signatures = "; ".join(f"{e.name}: {e.signature}" for e in effects if e.signature)
    advice = ("Curves at several " + " and ".join(PLURALS[q] for q in quantities) +
              " separate " + ("it" if len(effects) == 1 else "them")) if quantities else \
        "Data that vary what the effect depends on separate it"
    where = (" (" + "; ".join(fixed) + ")") if fixed else ""
    return f"{advice}{where}. Signatures: {signatures}." if signatures else f"{advice}{where}."
