"""Plug-in tables, one helper for all of them: Python entry points (``importlib.metadata``).

Every variant fogiac knows (targets, middlewares, importers, workloads, CLI verb groups) is an
entry point in a group named ``fogiac.<table>``; fogiac's own are declared in its
``pyproject.toml`` like anyone else's, so another installed package adds a target, a middleware
or a workload by declaring one more, with no edit to fogiac. An entry point is loaded when it is
first asked for: compiling for ``local`` loads nothing of ``aws``. Tests (and embedders) may
also :meth:`Registry.register` an object for the life of the process: a table that keeps objects
(the targets' drivers, the middlewares' halves) is a :class:`Registry`, never a dict of its own.
"""

from __future__ import annotations

import functools
import importlib
from collections.abc import Callable
from importlib import metadata
from typing import Any, Generic, TypeVar

from fogiac.errors import FogiacError, PlanError

T = TypeVar("T")


@functools.cache
def _declared(group: str) -> dict[str, metadata.EntryPoint]:
    """The entry points of ``group`` by name, read from the installed distributions once per process
    (the first look-up reads every distribution's metadata, about 25 ms here; later groups ~4 ms)."""
    return {point.name: point for point in metadata.entry_points(group=group)}


def shipped_metadata() -> tuple[str, dict[str, str]]:
    """fogiac's own distribution metadata as a ``*.dist-info`` folder's name and files, for code that is
    copied to a host rather than installed there: beside the copied packages, the host's Python finds
    the same entry points (the CLI's verbs, the middlewares) as this machine's."""
    dist = metadata.distribution("fogiac")
    files = {"METADATA": f"Metadata-Version: 2.1\nName: fogiac\nVersion: {dist.version}\n",
             "entry_points.txt": dist.read_text("entry_points.txt") or ""}
    return f"fogiac-{dist.version}.dist-info", files


def rescan() -> None:
    """Forget what was read, so a distribution installed (or put on ``sys.path``) since is seen."""
    _declared.cache_clear()
    load.cache_clear()


def names(group: str, *, own: bool = False) -> tuple[str, ...]:
    """Every name ``group`` declares, sorted (reads the distributions' metadata, loads nothing);
    ``own``: only those fogiac's own distribution declares (what its documentation lists)."""
    if own:
        return tuple(sorted(p.name for p in metadata.distribution("fogiac").entry_points if p.group == group))
    return tuple(sorted(_declared(group)))


def known(group: str, name: str) -> bool:
    return name in _declared(group)


@functools.cache
def load(group: str, name: str) -> Any:
    """The object entry point ``name`` of ``group`` names; an unknown name fails listing the known ones."""
    point = _declared(group).get(name)
    if point is None:
        raise PlanError(f"unknown {group.rpartition('.')[2]} {name!r}; valid: {', '.join(names(group))}")
    return point.load()


def resolve(ref: str) -> Any:
    """The object a ``module:attr`` reference names (what an entry's own references into its folder are)."""
    module, _, attr = ref.partition(":")
    return getattr(importlib.import_module(module), attr)


def value(group: str, name: str) -> str:
    """The ``module:attr`` (or module) entry point ``name`` of ``group`` names, without loading it."""
    point = _declared(group).get(name)
    if point is None:
        raise PlanError(f"unknown {group.rpartition('.')[2]} {name!r}; valid: {', '.join(names(group))}")
    return point.value


def find(group: str, name: str) -> Any:
    """:func:`load`, or None where ``group`` has no ``name`` (a plug-in that is optional)."""
    return load(group, name) if known(group, name) else None


class Registry(Generic[T]):
    """One table: ``get(name)`` loads an entry point of ``group`` (or returns a registered object).

    ``make`` turns what the entry point names into the table's object, once per name (a target's
    entry into its driver, a middleware's entry into one of its halves); several tables may read one
    group that way. An unknown name fails in one line naming the known ones, through ``error`` (a
    :class:`~fogiac.errors.FogiacError` the CLI prints without a traceback).
    """

    def __init__(self, group: str, *, what: str, error: Callable[[str], FogiacError] = PlanError,
                 make: Callable[[Any], T] | None = None) -> None:
        self.group = group
        self.what = what
        self.error = error
        self.make = make
        self._loaded: dict[str, T] = {}
        self._registered: dict[str, T] = {}

    def names(self) -> tuple[str, ...]:
        return tuple(sorted(set(self._registered) | set(_declared(self.group))))

    def get(self, name: str) -> T:
        if name in self._registered:
            return self._registered[name]
        if name not in self._loaded:
            point = _declared(self.group).get(name)
            if point is None:
                raise self.error(f"unknown {self.what} {name!r}; valid: {', '.join(self.names())}")
            found = point.load()
            self._loaded[name] = self.make(found) if self.make is not None else found
        return self._loaded[name]

    def ready(self, name: str) -> bool:
        """Whether ``name``'s object is at hand without loading anything (registered, or loaded already)."""
        return name in self._registered or name in self._loaded

    def value(self, name: str) -> str:
        """The entry point's ``module:attr`` text, without loading it (what a lazy table needs to know)."""
        if name not in _declared(self.group):
            raise self.error(f"unknown {self.what} {name!r}; valid: {', '.join(self.names())}")
        return _declared(self.group)[name].value

    def register(self, name: str, obj: T) -> T:
        """Add (or replace) ``obj`` under ``name`` for this process; returns it."""
        self._registered[name] = obj
        return obj

    def unregister(self, name: str) -> None:
        """Forget ``name``'s registered object and what was loaded for it (a plug-in uninstalled since)."""
        self._registered.pop(name, None)
        self._loaded.pop(name, None)
