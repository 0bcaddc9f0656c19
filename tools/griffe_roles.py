"""griffe extension for the manual's API pages: robocal's docstrings name other objects with Sphinx roles
(``:func:`robocal.data.load```, ``:class:`~robocal.Robot```), which mkdocstrings does not parse and would print as they
are. Each role becomes the code span a reader expects (``robocal.data.load``; the ``~`` form keeps the last name, as
Sphinx shows it). The docstrings themselves stay as they are: ``help()`` and IDEs read them."""

from __future__ import annotations

import re

import griffe

ROLE = re.compile(r":(?:py:)?(?:func|class|meth|mod|data|attr|exc|obj|const|ref):`(~?)([^`]+)`")


def _code(match: re.Match) -> str:
    name = match[2]
    return f"`{name.rsplit('.', 1)[-1] if match[1] else name}`"


class SphinxRoles(griffe.Extension):
    def on_object(self, *, obj, **kwargs) -> None:
        if obj.docstring is not None:
            obj.docstring.value = ROLE.sub(_code, obj.docstring.value)
