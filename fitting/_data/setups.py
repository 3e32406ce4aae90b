"""The setup registry of measurement files (see :mod:`fitting._data`, "Adding a setup kind")."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable


@dataclasses.dataclass(frozen=True)
class _SetupKind:
    """One entry of the setup registry.

    ``check_arguments(text)`` receives what follows ``kind:`` (``""`` when there is no
    colon) and returns ``None`` if valid, or a sentence saying what is wrong.
    """

    description: str
    check_arguments: Callable[[str], str | None]


def _no_arguments(arguments: str) -> str | None:
    if arguments:
        return f"takes no arguments, found {arguments!r}"
    return None


_SETUP_KINDS: dict[str, _SetupKind] = {
    "cantilever_tip": _SetupKind(
        description=(
            "horizontal tube clamped at the root, dead vertical tip load; deflection is "
            "the vertical tip displacement from the unloaded shape"
        ),
        check_arguments=_no_arguments,
    ),
}


def _setup_problem(setup: str) -> str | None:
    """Return what is wrong with a setup string, or ``None`` if it is valid."""
    known = ", ".join(_SETUP_KINDS)
    if not setup:
        return f"expected a setup (one of: {known}), found an empty field"
    kind, _, arguments = setup.partition(":")
    if kind not in _SETUP_KINDS:
        return f"expected a known setup (one of: {known}), found {setup!r}"
    problem = _SETUP_KINDS[kind].check_arguments(arguments)
    if problem is not None:
        return f"setup {kind!r} {problem}"
    return None
