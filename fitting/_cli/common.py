"""What every subcommand of the command line shares: argparse types and the atomic writer
of an output directory."""

from __future__ import annotations

import argparse
import math
import os
import shutil
import tempfile
from pathlib import Path


def positive_int(text: str) -> int:
    """argparse type: an integer > 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, found {text!r}")
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, found {text!r}")
    return value


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, found {text!r}")
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, found {text!r}")
    return value


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
