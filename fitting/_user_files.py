"""A user's own Python file, named on the command line or in a campaign as
``path/to/file.py:NAME`` (their own effects): imported once, its failure reported in words."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType


def import_user_file(file: Path, text: str) -> ModuleType:
    """Import ``file`` as a fresh module. ``text`` is what the user wrote (named in the
    message). Raises ``ValueError`` when the file does not import, with the error it raised."""
    spec = importlib.util.spec_from_file_location(f"jaxtube_user_file_{file.stem}", file)
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except Exception as error:  # the user's file: report, do not crash
        raise ValueError(f"effect {text!r}: importing {file} failed: {error}") from error
    return module
