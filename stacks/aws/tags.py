"""Tags every taggable resource carries: the plan's (``fogiac:stack`` first) plus a ``Name``.

``fogiac down`` sweeps leftovers by ``fogiac:stack``, so no component may forget them.
"""

from __future__ import annotations

from collections.abc import Mapping


def tagged(tags: Mapping[str, str], name: str) -> dict[str, str]:
    """``tags`` plus ``Name`` (unless the plan already names the resource)."""
    out = dict(tags)
    out.setdefault("Name", name)
    return out
