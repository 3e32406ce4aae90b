"""The whole ``jaxtube`` command line (console script ``jaxtube = "fitting._cli:main"``).

Nothing else in :mod:`fitting` imports this package; it imports the workbench and, through
its public namespace only, the engine.
"""

from .main import build_parser, main

__all__ = ["build_parser", "main"]
