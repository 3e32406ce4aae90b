"""A Griffe extension for the API reference: Sphinx roles in docstrings become code.

The docstrings name other objects as Sphinx does (``:func:`equilibrium```, ``:class:`Solution```);
Markdown has no roles, so each ``:role:`name``` is shown as the code span ``name``
(listed under ``extensions`` of the mkdocstrings handler in ``mkdocs.yml``).
"""

from __future__ import annotations

import re

import griffe

_ROLE = re.compile(r":(?:func|class|mod|meth|attr|data|obj|exc|const):`~?([^`]+)`")


class SphinxRolesAsCode(griffe.Extension):
    """Rewrite ``:role:`name``` as ```name``` in every docstring Griffe loads."""

    def on_instance(self, *, obj: griffe.Object, **kwargs) -> None:
        if obj.docstring is not None:
            obj.docstring.value = _ROLE.sub(r"`\1`", obj.docstring.value)
