"""A griffe extension for the API pages (mkdocs.yml): the Sphinx cross-reference roles of uamfleet's docstrings
(``:func:`uamfleet.parallel_env```, ``:class:`~uamfleet.config.EnvConfig```) become Markdown inline code, so the
pages show the name instead of the role's markup. ``~`` keeps the last dotted part, as Sphinx shows it."""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:py:)?(?:func|class|meth|attr|mod|data|obj|exc|const):`(~?)([^`]+)`")


def plain(text: str) -> str:
    """``text`` with every Sphinx role written as inline code."""
    return ROLE.sub(lambda m: f"`{m.group(2).rsplit('.', 1)[-1] if m.group(1) else m.group(2)}`", text)


class SphinxRoles(griffe.Extension):
    """Rewrites the roles in every docstring griffe reads."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = plain(obj.docstring.value)
