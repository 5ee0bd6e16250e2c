"""Targets: where a manifest's "cloud" nodes run, one registry and one module or folder each.

::

    aws/      EC2 machines, VPC and Client VPN through Pulumi (the only user of boto3, pulumi, stacks/)
    hosts/    machines that already exist, reached over SSH (a lab GPU server is fog too)
    local/    sandboxes on this machine, one ROS master each (demos, CI)

A new target is one :class:`~fogiac.targets.base.Target` passed to :func:`register`; nothing
else in fogiac names a target.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

from fogiac.errors import PlanError
from fogiac.plan.placement import Placement
from fogiac.targets.base import Target

Place = Callable[..., Placement]  # place(manifest, *, stack, tags) -> Placement, as Target.place

# The built-in targets, imported when first asked for: compiling for ``local`` loads nothing of ``aws``.
BUILTIN: dict[str, str] = {"aws": "fogiac.targets.aws.target:AWS", "hosts": "fogiac.targets.hosts.target:HOSTS",
                           "local": "fogiac.targets.local.target:LOCAL"}
# Where a built-in target's placement lives apart from its lifecycle, so that compiling (``validate``,
# ``plan``, ``graph``) loads what the target decides at compile time and not its provisioning and engine.
PLACEMENT: dict[str, str] = {name: f"fogiac.targets.{name}.placement:place" for name in BUILTIN}
# Other formats a target's plan document exports to, by (target, format): what ``plan --format`` prints.
EXPORTERS: dict[tuple[str, str], str] = {("aws", "terraform-json"): "fogiac.targets.aws.tfplan:export"}
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


def placer(name: str) -> Place:
    """``name``'s ``place``: from its placement module when it has one and is not loaded yet."""
    if name not in _REGISTRY and name in PLACEMENT:
        module, attr = PLACEMENT[name].split(":")
        found: Place = getattr(importlib.import_module(module), attr)
        return found
    return get(name).place


def exporter(name: str, fmt: str) -> Callable[[Mapping[str, Any]], dict[str, Any]]:
    """How target ``name`` writes its plan document as ``fmt``; fails in one line naming what exists."""
    if (name, fmt) not in EXPORTERS:
        known = ", ".join(f"{t} ({f})" for t, f in sorted(EXPORTERS)) or "none"
        raise PlanError(f"target {name!r} cannot export its plan as {fmt!r}; available: {known}")
    module, attr = EXPORTERS[(name, fmt)].split(":")
    found: Callable[[Mapping[str, Any]], dict[str, Any]] = getattr(importlib.import_module(module), attr)
    return found


def names() -> tuple[str, ...]:
    return tuple(sorted(set(_REGISTRY) | set(BUILTIN)))
