"""The diagnosis study (issue 34): random designs from the independent continuum solver
(:mod:`.designs`), each diagnosed on a Dask cluster and stored as it ends (:mod:`.run`),
the tables against the issue's targets (:mod:`.summary`), and the noise estimate against
the designs' floors without a diagnosis (:mod:`.noise`); the figure is
:func:`fitting.study_figure`. Driven by ``experiments/diagnosis_study.py``."""
