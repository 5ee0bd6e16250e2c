"""What a target is: the :class:`Target` protocol and the records its verbs take and return.

A target decides where "cloud" nodes run. It answers compile (:meth:`Target.place`) and every
verb of the CLI that touches machines: ``up``, ``down``, ``status``, ``doctor``, ``refresh``,
``sweep``, and how its status reads in a terminal. Rendering and asking are callbacks from
the CLI: a target decides, the CLI shows.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

from fogiac.manifest.schema import Manifest
from fogiac.plan.model import Plan
from fogiac.plan.placement import Placement, Tags
from fogiac.state import stack_dir


@dataclass(frozen=True)
class UpOptions:
    manifest_path: Path
    yes: bool = False
    ssh_from: str | None = None
    show: Callable[[Mapping[str, Any], Any], None] = lambda doc, report: None  # the plan document, preflight
    confirm: Callable[[str], bool] = lambda question: False
    announce: Callable[[str], None] = lambda line: None
    on_event: Callable[[Any], None] | None = None
    start_edge_master: bool = False  # the demo's edge: fogiac runs the robot-side roscore too
    edge_master: str | None = None  # overrides the manifest's edge.ros_master
    infra_only: bool = False  # create machines, provision nothing (targets that create machines)


@dataclass(frozen=True)
class UpResult:
    outputs: Mapping[str, Any]
    applied: Path
    report: Any = None  # the provisioning report (fogiac.provision.runner.ProvisionReport), if any
    relays: Mapping[str, str] = field(default_factory=dict)  # host -> HOST:PORT the edge relay dials
    edge_master: str = ""
    plan: Plan | None = None  # the plan as applied, where the target changed it (a spot host fell back to on-demand)


@dataclass(frozen=True)
class DownOptions:
    keep_network: bool = False
    on_event: Callable[[Any], None] | None = None


@dataclass(frozen=True)
class DownResult:
    engine_errors: tuple[str, ...]
    left: tuple[str, ...]  # what is still there: resources tagged with the stack, processes, sandboxes
    not_checked: tuple[str, ...]
    deleted: tuple[str, ...] = ()
    kept_usd_per_hour: float | None = None  # with --keep-network: what the kept network costs
    existed: bool = True  # False: nothing of the stack was there (and down created nothing)

    @property
    def clean(self) -> bool:
        """Nothing of the stack is left (engine errors the sweep made good do not count)."""
        return not self.left


@dataclass(frozen=True)
class Check:
    """One line of ``fogiac doctor``."""

    what: str
    ok: bool
    detail: str


@dataclass(frozen=True)
class Refreshed:
    """One line of ``fogiac refresh``."""

    what: str
    ok: bool
    summary: str


@dataclass(frozen=True)
class SweepOutcome:
    found: tuple[str, ...] = ()
    deleted: tuple[str, ...] = ()
    left: tuple[str, ...] = ()
    errors: tuple[str, ...] = ()
    not_checked: tuple[str, ...] = ()
    note: str = ""  # a target with nothing to sweep says why, in one line


@runtime_checkable
class Target(Protocol):
    """Where a manifest's cloud nodes run. Register one with :func:`fogiac.targets.register`."""

    name: str
    summary: str  # one line, for --help and error messages
    makes_resources: bool  # creates machines or cloud resources (so there is something to sweep)

    def place(self, manifest: Manifest, *, stack: str, tags: Tags) -> Placement:
        """Compile's question: hosts, which node runs where, network, security groups, cost."""
        ...

    def declare(self, plan: Plan) -> tuple[Mapping[str, Any], ...]:
        """The resources ``up`` would create, as plan-document rows (none where nothing is created)."""
        ...

    def up(self, plan: Plan, opts: UpOptions) -> UpResult: ...

    def down(self, plan: Plan, opts: DownOptions) -> DownResult: ...

    def status(self, plan: Plan) -> dict[str, Any]:
        """JSON-ready: ``{"stack", "target", "hosts": [...]}`` plus whatever the target knows."""
        ...

    def render_status(self, doc: Mapping[str, Any]) -> list[Any]:
        """Rich renderables (or plain strings) for ``fogiac status``."""
        ...

    def doctor(self, plan: Plan, *, ssh_from: str | None = None) -> list[Check]:
        """Every check ``up`` would make; nothing is created."""
        ...

    def refresh(self, plan: Plan) -> list[Refreshed]: ...

    def sweep(self, plan: Plan, *, dry_run: bool) -> SweepOutcome: ...


@contextmanager
def untouched_on_failure(stack: str) -> Iterator[Callable[[], None]]:
    """Remove the stack folder again if this run created it and fails before ``commit()``."""
    existed = stack_dir(stack, create=False).exists()
    committed = False

    def commit() -> None:
        nonlocal committed
        committed = True

    try:
        yield commit
    except BaseException:
        path = stack_dir(stack, create=False)
        if not existed and not committed and path.exists():
            shutil.rmtree(path, ignore_errors=True)
        raise
