"""Figures of fits, predictions and diagnoses (:mod:`.plots`; matplotlib's object API, no
pyplot)."""
