"""A launch package's requirements file, read the same way by ``validate`` and by ``up``.

Only package specifiers: pip options (``-r``, ``--index-url``, ...) would escape the digest that
caches a host's virtual environment, and the index comes from the host's own pip settings.
"""

from __future__ import annotations

import re


class RequirementsProblem(ValueError):
    """One line: ``where:line: option: why``."""


def specifiers(text: str, *, where: str) -> tuple[str, ...]:
    """The requirement lines of ``text`` (comments and blank lines dropped, spaces squeezed out)."""
    found: list[str] = []
    for number, line in enumerate(text.splitlines(), 1):
        spec = line.split(" #", 1)[0].strip()
        if not spec or spec.startswith("#"):
            continue
        if spec.startswith("-"):
            raise RequirementsProblem(f"{where}:{number}: {spec.split()[0]}: only package specifiers are allowed "
                                      "here; the host's pip settings choose the index")
        found.append(re.sub(r"\s+", "", spec))
    return tuple(found)
