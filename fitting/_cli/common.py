"""What the subcommands of the command line share: argparse types, the check of ``--out`` and
of the measurement file, and the atomic writer of an output directory."""

from __future__ import annotations

import argparse
import math
import os
import shutil
import sys
import tempfile
from pathlib import Path

from .._data import DataError, load_measurements


def add_data_argument(parser: argparse.ArgumentParser) -> None:
    """The positional measurement file of ``fit`` and ``diagnose`` (:mod:`fitting._data`)."""
    parser.add_argument("data", type=Path, help="measurement CSV (curve,setup,pressure_bar,"
                                                "radius_m,length_m,deflection_mm,force_N)")


def add_model_size_arguments(parser: argparse.ArgumentParser) -> None:
    """``--pivots`` and ``--segments``: the size of the model of ``fit`` and ``diagnose``."""
    parser.add_argument("--pivots", type=pivot_counts, default=(1, 1, 1),
                        help="pivots per regime: unwrinkled,wrinkled,collapsed (default 1,1,1)")
    parser.add_argument("--segments", type=positive_int, default=None,
                        help="rigid segments of the model tube (default 12)")


def add_structure_source_arguments(parser: argparse.ArgumentParser, kite_fem_help: str) -> None:
    """The structure a command reads: a TOML spec, or with ``--kite-fem`` a kite_fem model
    with its pressure [bar] and a factor on Breukels' 2011 bending law."""
    parser.add_argument("spec", type=Path, nargs="?", default=None,
                        help="the TOML spec file (or --kite-fem)")
    parser.add_argument("--kite-fem", type=Path, default=None, metavar="NPZ", help=kite_fem_help)
    parser.add_argument("--pressure-bar", type=positive_float, default=None,
                        help="with --kite-fem: tube pressure [bar] (default: the file's)")
    parser.add_argument("--bending-scale", type=positive_float, default=None,
                        help="with --kite-fem: factor on Breukels' 2011 bending law")


def _positive(text: str, convert, noun: str):
    """``convert(text)`` if it is a finite number > 0, else an argparse error naming ``noun``."""
    try:
        value = convert(text)
    except ValueError:
        value = None
    if value is None or not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive {noun}, found {text!r}")
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer > 0."""
    return _positive(text, int, "integer")


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    return _positive(text, float, "number")


def pivot_counts(text: str) -> tuple[int, int, int]:
    """argparse type: pivots per regime, ``unwrinkled,wrinkled,collapsed`` (e.g. ``2,2,1``)."""
    try:
        counts = tuple(int(v) for v in text.split(","))
    except ValueError:
        counts = ()
    if len(counts) != 3 or min(counts) < 1:
        raise argparse.ArgumentTypeError(
            f"expected three positive integers like 2,2,1 (unwrinkled, wrinkled, collapsed "
            f"pivots), found {text!r}")
    return counts


def bad_output_directory(out: Path) -> bool:
    """Whether ``--out`` names an existing file (then says so on stderr: exit code 2)."""
    if out.exists() and not out.is_dir():
        print(f"error: --out {out} exists and is not a directory", file=sys.stderr)
        return True
    return False


def load_input(args):
    """The measurements of ``args.data`` for a command writing into ``args.out``, or None
    after printing why not (bad output directory, bad data: exit code 2, nothing written)."""
    if bad_output_directory(args.out):
        return None
    try:
        return load_measurements(args.data)
    except DataError as error:
        print(f"error: {error}", file=sys.stderr)
        return None


def write_directory(out: Path, writers: dict) -> None:
    """Write files atomically: each ``writers[name](path)`` writes into a temporary directory
    next to ``out``, which is then renamed to ``out`` (or, if ``out`` exists, each file is
    moved over its namesake). A failure leaves ``out`` as it was: nothing half-written."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(f"--out {out} exists and is not a directory")
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial", dir=out.parent))
    try:
        for name, write in writers.items():
            write(staging / name)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(staging, 0o777 & ~umask)
        if out.is_dir():
            for name in sorted(p.name for p in staging.iterdir()):
                os.replace(staging / name, out / name)
            staging.rmdir()
        else:
            os.replace(staging, out)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
