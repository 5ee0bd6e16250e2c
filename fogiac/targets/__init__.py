"""Targets: where a manifest's "cloud" nodes run, one entry point and one folder each.

::

    aws/      EC2 machines, VPC and Client VPN through Pulumi (the only user of boto3, pulumi, stacks/aws/)
    hosts/    machines that already exist, reached over SSH (a lab GPU server is fog too)
    local/    sandboxes on this machine, one ROS master each (demos, CI)

A target is a :class:`TargetEntry` published under the ``fogiac.targets`` entry point group
(fogiac's own in its ``pyproject.toml``): its name, the compile-time placement, the driver the
lifecycle asks (:class:`~fogiac.lifecycle.driver.Target`) and its manifest ``cloud:`` variant,
each loaded only when asked for. Nothing else in fogiac names a target.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from fogiac import registry
from fogiac.errors import PlanError
from fogiac.registry import Registry

if TYPE_CHECKING:  # not at run time: a target's ``cloud:`` variant (``targets/<name>/manifest.py``) is loaded
    # while the manifest's models are being built, before the lifecycle (which imports them) can be
    from fogiac.lifecycle.driver import Target
    from fogiac.plan.placement import Placement

Place = Callable[..., "Placement"]  # place(manifest, *, stack, tags) -> Placement, as Target.place


@dataclass(frozen=True)
class TargetEntry:
    """What a target publishes: ``module:attr`` references into its own folder, loaded when first needed.

    ``placement`` is what compiling (``validate``, ``plan``, ``graph``) loads; ``driver`` is what
    ``up``, ``down`` and ``status`` load; a target whose driver is light may name only ``driver``.
    """

    name: str
    driver: str
    placement: str = ""
    exporters: Mapping[str, str] = field(default_factory=dict)  # format -> how the plan document becomes it

    def load_driver(self) -> Target:
        found: Target = registry.resolve(self.driver)
        return found

    def load_placement(self) -> Place:
        found: Place = registry.resolve(self.placement) if self.placement else self.load_driver().place
        return found


ENTRIES: Registry[TargetEntry] = Registry("fogiac.targets", what="target")
DRIVERS: Registry[Target] = Registry("fogiac.targets", what="target", make=lambda entry: entry.load_driver())


def register(target: Target) -> Target:
    """Add (or replace) a driver object under its name for this process; returns it."""
    return DRIVERS.register(target.name, target)


def unregister(name: str) -> None:
    DRIVERS.unregister(name)


def get(name: str) -> Target:
    """The target called ``name``; an unknown name fails in one line listing the known ones."""
    return DRIVERS.get(name)


def placer(name: str) -> Place:
    """``name``'s ``place``: from its placement module when it has one and its driver is not loaded yet."""
    if DRIVERS.ready(name):
        return DRIVERS.get(name).place
    return _entry(name).load_placement()


def exporter(name: str, fmt: str) -> Callable[[Mapping[str, Any]], dict[str, Any]]:
    """How target ``name`` writes its plan document as ``fmt`` (``plan --format``); fails in one line
    naming what exists."""
    ref = _entry(name).exporters.get(fmt) if name in ENTRIES.names() else None
    if ref is None:
        known = ", ".join(f"{t} ({f})" for t in ENTRIES.names() for f in sorted(_entry(t).exporters)) or "none"
        raise PlanError(f"target {name!r} cannot export its plan as {fmt!r}; available: {known}")
    found: Callable[[Mapping[str, Any]], dict[str, Any]] = registry.resolve(ref)
    return found


def names() -> tuple[str, ...]:
    return DRIVERS.names()


def _entry(name: str) -> TargetEntry:
    return ENTRIES.get(name)
