"""The workloads a node may name (``workload: NAME``): entry points of the ``fogiac.workloads`` group,
each naming its container recipe module (``requirements()``, ``dockerfile()``, ``FLAVOURS``) inside
the workload's package, whose ``python -m PACKAGE node`` runs the node."""

from __future__ import annotations

from types import ModuleType

from fogiac import registry

GROUP = "fogiac.workloads"


def recipe(name: str) -> ModuleType:
    """The workload's container recipe module."""
    found: ModuleType = registry.load(GROUP, name)
    return found


def package(name: str) -> str:
    """The workload's Python package (what ``python -m`` runs), read from its entry point without importing it."""
    return registry.value(GROUP, name).partition(":")[0].rpartition(".")[0]
