"""One small registry helper: named plug-ins by Python entry point, with fogiac's built-ins beside them.

A table of plug-ins is a *group* (``fogiac.clouds``, ...). A name resolves to the object an entry
point of that group names (``[project.entry-points."fogiac.clouds"]`` in a package's
pyproject.toml), or, when no installed package declares it, to fogiac's own ``"module:attr"``
string in :data:`BUILTIN`. The built-ins are looked up first, without reading any distribution's
metadata (scanning every installed distribution costs ``fogiac validate`` ~10 ms of its 300), so
the scan runs only for a name that is not built in; an entry point cannot replace a built-in.
Objects are imported when first asked for, so a group lists names without loading their code.
"""

from __future__ import annotations

import importlib
from functools import cache
from importlib.metadata import entry_points
from typing import Any

from fogiac.errors import PlanError

# group -> name -> "module:attr": what fogiac itself ships (pyproject.toml declares the same).
BUILTIN: dict[str, dict[str, str]] = {
    # A target's part of the manifest's ``cloud:`` block: its fields' checks and its machine choice.
    "fogiac.clouds": {
        "aws": "fogiac.catalogue:AWS",
        "hosts": "fogiac.targets.hosts.manifest:CLOUD",
        "local": "fogiac.targets.local.manifest:CLOUD",
    },
    # Which input changes replace a resource, per Pulumi package (a type token's first part).
    "fogiac.replacements": {"aws": "fogiac.targets.aws.replace:forces_replacement"},
    # The inputs `fogiac plan` shows per resource type, per Pulumi package.
    "fogiac.key_inputs": {"aws": "fogiac.targets.aws.display:KEY_INPUTS"},
    # Sub-commands a target adds to the CLI: name -> a function returning a typer app.
    "fogiac.commands": {"vpn": "fogiac.targets.aws.vpncli:commands"},
    # What the manifest asks of the middleware a ROS distribution picks.
    "fogiac.middleware": {"for_distro": "fogiac.net.middleware:for_distro"},
}


@cache
def _installed(group: str) -> dict[str, str]:
    return {ep.name: ep.value for ep in entry_points(group=group)}


def _where(group: str, name: str) -> str | None:
    return BUILTIN.get(group, {}).get(name) or _installed(group).get(name)


def names(group: str, *, installed: bool = True) -> tuple[str, ...]:
    """Every name in ``group``, sorted: the built-ins and (unless ``installed`` is False) entry points."""
    found = set(BUILTIN.get(group, {}))
    if installed:
        found |= set(_installed(group))
    return tuple(sorted(found))


def known(group: str, name: str) -> bool:
    """Whether ``group`` has ``name`` (the distributions are read only when it is not built in)."""
    return _where(group, name) is not None


def find(group: str, name: str) -> Any:
    """:func:`load`, or None where ``group`` has no ``name`` (a plug-in that is optional)."""
    return load(group, name) if known(group, name) else None


@cache
def load(group: str, name: str) -> Any:
    """The object ``name`` stands for in ``group``; an unknown name fails listing the known ones."""
    where = _where(group, name)
    if where is None:
        raise PlanError(f"unknown {group.rpartition('.')[2]} {name!r}; valid: {', '.join(names(group))}")
    module, _, attr = where.partition(":")
    found = importlib.import_module(module)
    for part in attr.split(".") if attr else ():
        found = getattr(found, part)
    return found
