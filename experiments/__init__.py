"""The studies, figures and benchmarks of jaxtube (scripts, not part of the installed package).

Each runs from the repository root as a module, ``python -m experiments.NAME``, so that
``jaxtube``, ``fitting`` and the shared parts here (``experiments._synthetic``) import
without any edit of ``sys.path``.
"""
