"""Targets: where a manifest's "cloud" nodes run, one registry and one module or folder each.

::

    aws/      EC2 machines, VPC and Client VPN through Pulumi (the only user of boto3, pulumi, stacks/)
    hosts.py  machines that already exist, reached over SSH (a lab GPU server is fog too)
    local.py  sandboxes on this machine, one ROS master each (demos, CI)

A new target is one :class:`~fogiac.targets.base.Target` passed to :func:`register`; nothing
else in fogiac names a target.
"""

from __future__ import annotations

import importlib

from fogiac.errors import PlanError
from fogiac.targets.base import Target

# The built-in targets, imported when first asked for: compiling for ``local`` loads nothing of ``aws``.
BUILTIN: dict[str, str] = {"aws": "fogiac.targets.aws:AWS", "hosts": "fogiac.targets.hosts:HOSTS",
                           "local": "fogiac.targets.local:LOCAL"}
_REGISTRY: dict[str, Target] = {}


def register(target: Target) -> Target:
    """Add (or replace) ``target`` under its name; returns it, so it can decorate an instance."""
    _REGISTRY[target.name] = target
    return target


def unregister(name: str) -> None:
    _REGISTRY.pop(name, None)


def get(name: str) -> Target:
    """The target called ``name``; an unknown name fails in one line listing the known ones."""
    found = _REGISTRY.get(name)
    if found is None and name in BUILTIN:
        module, attr = BUILTIN[name].split(":")
        found = register(getattr(importlib.import_module(module), attr))
    if found is None:
        raise PlanError(f"unknown target {name!r}; valid: {', '.join(names())}")
    return found


def names() -> tuple[str, ...]:
    return tuple(sorted(set(_REGISTRY) | set(BUILTIN)))
