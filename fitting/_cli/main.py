"""The ``jaxtube`` command line: one parser, one subcommand per module of this package.

- ``jaxtube simulate SPEC.toml --out DIR``: a structure spec's load path (:mod:`.simulate`).
- ``jaxtube fit DATA.csv --out DIR`` / ``jaxtube predict ...``: calibration (:mod:`.fit`).
- ``jaxtube diagnose DATA.csv --out DIR [--effect FILE.py:Class]`` / ``jaxtube demo``: which
  physical effect the model lacks (:mod:`.diagnose`).
- ``jaxtube sweep ...``: a law over a pressure x radius x length grid (:mod:`.sweep`).
- ``jaxtube score-shape --markers M.csv --positions P.csv --tubes T.csv --out DIR``: a
  solved shape against measured markers (:mod:`.score_shape`).

Compiled programs are kept between runs in a persistent cache under the user's cache
directory (``jaxtube.enable_compilation_cache``: ``$XDG_CACHE_HOME/jaxtube/xla``), so a second
run of the same command does not compile again, and the fit's traced program is stored beside
it (``jaxtube.enable_traced_program_store``: ``$XDG_CACHE_HOME/jaxtube/traced``), so a second
run does not trace it again either; ``--no-compilation-cache`` or
``JAXTUBE_NO_COMPILATION_CACHE=1`` turns both off.

Exit codes (every subcommand): 0 success; 1 the run finished but some solves did not
converge (outputs written, failures marked); 2 bad input or bad arguments (nothing written).
"""

from __future__ import annotations

import argparse
import sys

import jaxtube as jt

from .diagnose import add_demo, add_diagnose
from .fit import add_fit, add_predict
from .modes import add_modes
from .score_shape import add_score_shape
from .shape import add_shape
from .simulate import add_simulate
from .sweep import add_sweep

# One function per subcommand registers its parser; add a new subcommand here.
SUBCOMMANDS = (add_simulate, add_fit, add_predict, add_diagnose, add_demo, add_sweep,
               add_score_shape, add_modes, add_shape)


def build_parser() -> argparse.ArgumentParser:
    """The ``jaxtube`` argument parser, with one subparser per subcommand."""
    parser = argparse.ArgumentParser(
        prog="jaxtube", description="Differentiable simulator of inflatable tube structures.")
    parser.add_argument("--version", action="version", version=f"jaxtube {jt.__version__}")
    parser.add_argument(
        "--no-compilation-cache", action="store_true",
        help="do not keep compiled and traced programs in the user's cache directory "
             "between runs (default: kept under $XDG_CACHE_HOME/jaxtube/xla and "
             "$XDG_CACHE_HOME/jaxtube/traced; also JAXTUBE_NO_COMPILATION_CACHE=1)")
    subparsers = parser.add_subparsers(title="subcommands", metavar="COMMAND")
    for add in SUBCOMMANDS:
        add(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``jaxtube`` command (console script); returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not hasattr(args, "run"):
        parser.print_help(sys.stderr)
        return 2
    if not args.no_compilation_cache:
        jt.enable_compilation_cache()
        jt.enable_traced_program_store()
    return args.run(args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
