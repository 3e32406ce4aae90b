"""The diagnosis study (issue 34): random designs from the independent continuum solver
(:mod:`.designs`), each diagnosed on a Dask cluster and stored as it ends (:mod:`.run`),
and the tables against the issue's targets (:mod:`.summary`); the figure is
:func:`fitting.study_figure`. Driven by ``experiments/diagnosis_study.py``."""
