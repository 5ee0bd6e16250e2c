"""A launch package's requirements file, read the same way by ``validate`` and by ``up``.

Only package specifiers: pip options (``-r``, ``--index-url``, ...) would escape the digest that
caches a host's virtual environment, and the index comes from the host's own pip settings. Only
released packages by name: a PEP 508 direct reference (``name @ URL``), a URL or a path is built from
source wherever pip meets it, which with carried wheels (``FOGIAC_CARRY_WHEELS=1``) is the operator's
own machine, running whatever build code the reference points at.
"""

from __future__ import annotations

import re


class RequirementsProblem(ValueError):
    """One line: ``where:line: option: why``."""


# A project name (PEP 508), then only extras, versions and their operators: no '@', '/', ':' or '\',
# so no URL, direct reference or path reaches pip. The marker after ';' is free text in quotes.
_BY_NAME = re.compile(r"[A-Za-z0-9](?:[A-Za-z0-9._-]*[A-Za-z0-9])?[][A-Za-z0-9._,<>=!~*+()-]*")
# pip takes a bare name ending like an archive for a file beside it.
_ARCHIVE = (".whl", ".zip", ".tar", ".tar.gz", ".tgz", ".tar.bz2", ".tbz", ".tar.xz", ".txz", ".tar.lz")


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
        spec = re.sub(r"\s+", "", spec)
        requirement = spec.split(";", 1)[0]
        if not _BY_NAME.fullmatch(requirement) or requirement.lower().endswith(_ARCHIVE):
            raise RequirementsProblem(f"{where}:{number}: {requirement[:80]!r}: only released packages by name "
                                      "(and version) are allowed here; a URL, path or `name @ URL` reference "
                                      "would be built from source where pip runs")
        found.append(spec)
    return tuple(found)
