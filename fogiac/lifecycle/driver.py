"""What a target is to the lifecycle: the :class:`Target` driver protocol and the records its answers take and return.

A target decides where "cloud" nodes run. It answers compile (:meth:`Target.place`) and the
questions the lifecycle asks while it runs ``up``, ``down`` and ``status`` (:mod:`fogiac.lifecycle`),
plus ``doctor``, ``refresh`` and ``sweep``. Rendering and asking are callbacks from the CLI: a
target decides, the CLI shows.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

from fogiac.lifecycle.events import OnEvent
from fogiac.manifest.schema import Manifest
from fogiac.plan.model import Plan
from fogiac.plan.placement import Placement, Tags


class Feature(str, Enum):
    """What a target can do, declared (as SkyPilot's clouds declare theirs), never detected by callers."""

    CREATES_MACHINES = "creates machines"  # makes and destroys machines (else they exist; down stops what runs)
    # fogiac provisions each host over the runner the target hands back (``reach``), and down stops what it
    # started there; a target whose platform runs the nodes itself declares nothing of the kind: its
    # ``create`` starts them and its ``reach`` answers only the links the edge dials
    PROVISIONS = "provisions hosts"
    INFRA_ONLY = "infra only"  # up --infra-only: make the machines, provision nothing
    KEEP_NETWORK = "keep network"  # down --keep-network: a network layer that outlives the machines
    # a fleet's robot holds a credential of the target's network too (aws: its Client VPN certificate), which
    # ``robot revoke``/``restore`` has the target refuse or accept again (:class:`RobotRefuser`)
    REFUSES_ROBOTS = "refuses robots"


@dataclass(frozen=True)
class UpOptions:
    manifest_path: Path
    yes: bool = False
    ssh_from: str | None = None
    # the plan document, then the target's summary lines (None: show the plan itself)
    show: Callable[[Mapping[str, Any], tuple[str, ...] | None], None] = lambda doc, summary: None
    confirm: Callable[[str], bool] = lambda question: False
    announce: Callable[[str], None] = lambda line: None
    on_event: OnEvent | None = None
    start_edge_master: bool = False  # the demo's edge: fogiac runs the robot-side roscore too
    edge_master: str | None = None  # overrides the manifest's edge.ros_master
    infra_only: bool = False  # create machines, provision nothing (targets with Feature.INFRA_ONLY)


@dataclass(frozen=True)
class Machine:
    """One machine a target made, as ``up`` reports it."""

    host: str
    id: str
    machine: str
    public: str | None = None
    private: str | None = None


@dataclass(frozen=True)
class UpResult:
    outputs: Mapping[str, Any]
    applied: str  # where the record of what was applied is kept
    report: Any = None  # the provisioning report (fogiac.provision.runner.ProvisionReport), if any
    relays: Mapping[str, str] = field(default_factory=dict)  # host -> HOST:PORT the edge relay dials
    edge_master: str = ""
    plan: Plan | None = None  # the plan as applied, where the target changed it (a spot host fell back to on-demand)
    machines: tuple[Machine, ...] = ()


@dataclass(frozen=True)
class DownOptions:
    keep_network: bool = False
    on_event: OnEvent | None = None


@dataclass(frozen=True)
class DownResult:
    engine_errors: tuple[str, ...]
    left: tuple[str, ...]  # what is still there: resources tagged with the stack, processes, sandboxes
    not_checked: tuple[str, ...]
    deleted: tuple[str, ...] = ()
    kept: str | None = None  # with --keep-network: what is kept and what it costs, one line
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


@dataclass(frozen=True)
class Prepared:
    """A target's answer before the question: the plan it will apply, and what the user is asked."""

    plan: Plan
    question: str
    summary: tuple[str, ...] | None = None  # shown instead of the plan itself (a preflight's findings)
    notices: tuple[str, ...] = ()  # said after the summary, before the question
    facts: Any = None  # the target's own findings, handed back to its ``create``


@dataclass(frozen=True)
class Created:
    """What ``create`` made: the plan as applied, the engine's outputs, the machines to report."""

    plan: Plan
    outputs: Mapping[str, Any] = field(default_factory=dict)
    machines: tuple[Machine, ...] = ()


@dataclass(frozen=True)
class Reach:
    """What a target hands back once its machines are there: the command runner for each host (as
    SkyPilot's ``get_command_runners``), the ``HOST:PORT`` the robot's edge dials for each, and what the
    host's services listen on where the target chose it (else the plan says).

    A target without :attr:`Feature.PROVISIONS` hands back no runner: its platform runs the nodes and
    the middleware's host end, and ``connect`` is all the lifecycle needs to start the edge's end.
    """

    access: Mapping[str, Any]  # host -> fogiac.provision.HostAccess
    connect: Mapping[str, str]
    ports: Mapping[str, Any] = field(default_factory=dict)  # host -> fogiac.provision.HostPorts


@dataclass(frozen=True)
class Destroyed:
    """What ``destroy`` did. Its errors do not block forgetting the stack: only what is ``left`` does."""

    errors: tuple[str, ...] = ()
    left: tuple[str, ...] = ()
    not_checked: tuple[str, ...] = ()
    deleted: tuple[str, ...] = ()
    kept: str | None = None  # what stays on purpose (down --keep-network), one line


class RobotRefuser(Protocol):
    """What a target with :attr:`Feature.REFUSES_ROBOTS` answers besides :class:`Target`'s questions."""

    def refuse_revoked(self, plan: Plan) -> str:
        """Have the target's network refuse exactly the robots the record keeps revoked (and those dropped from
        the manifest); one line says what it refuses now."""
        ...


@runtime_checkable
class Target(Protocol):
    """Where a manifest's cloud nodes run: a driver that answers the lifecycle's questions.

    The lifecycle (:mod:`fogiac.lifecycle`) owns the sequence of ``up``, ``down`` and ``status``
    (show, ask, lock, record, edge, create, provision and connect, applied); a target answers
    only what differs between clouds. Register one through the ``fogiac.targets`` entry point.
    """

    name: str
    summary: str  # one line, for --help and error messages
    features: frozenset[Feature]

    def place(self, manifest: Manifest, *, stack: str, tags: Tags) -> Placement:
        """Compile's question: hosts, which node runs where, network, security groups, cost."""
        ...

    def declare(self, plan: Plan) -> tuple[Mapping[str, Any], ...]:
        """The resources ``up`` would create, as plan-document rows (none where nothing is created)."""
        ...

    def ready(self, plan: Plan, *, verb: str) -> None:
        """Raise, in one line, if ``verb`` cannot run at all (a missing tool, no credentials); touches no state."""
        ...

    def prepare(self, plan: Plan, *, ssh_from: str | None) -> Prepared:
        """Under the stack's lock, before the question: preflight, and the plan as it will be applied."""
        ...

    def create(self, plan: Plan, prepared: Prepared, *, announce: Callable[[str], None],
               on_event: OnEvent | None) -> Created:
        """Make (or start again) the machines; the deployment is recorded already, so ``down`` finds them."""
        ...

    def reach(self, plan: Plan, created: Created, *, announce: Callable[[str], None]) -> Reach:
        """Each host's runner and the links the edge dials (only the links where the platform runs the nodes)."""
        ...

    def access_from(self, description: Mapping[str, Any]) -> Any:
        """A recorded host's runner again (a ``fogiac.provision.HostAccess``), from the ``describe()`` this
        target's access wrote: ``logs``, ``ssh``, ``status`` and ``down`` find the host as it was reached."""
        ...

    def recorded(self, plan: Plan) -> bool:
        """Whether this target knows anything of the stack (so ``down`` has something to undo)."""
        ...

    def destroy(self, plan: Plan, opts: DownOptions) -> Destroyed:
        """Remove the machines (a target whose machines exist: what it left on them), then prove it."""
        ...

    def forget(self, plan: Plan, *, keep_network: bool) -> None:
        """Drop the target's own records once ``destroy`` left nothing."""
        ...

    def describe(self, plan: Plan, *, now: float) -> dict[str, Any]:
        """JSON-ready facts for ``status``: ``hosts`` rows and the ``cost`` guard, plus the target's own."""
        ...

    def render_status(self, doc: Mapping[str, Any]) -> list[Any]:
        """Rich renderables (or plain strings) of the target's part of ``fogiac status``."""
        ...

    def doctor(self, plan: Plan, *, ssh_from: str | None = None) -> list[Check]:
        """Every check ``up`` would make; nothing is created."""
        ...

    def refresh(self, plan: Plan) -> list[Refreshed]: ...

    def sweep(self, plan: Plan, *, dry_run: bool) -> SweepOutcome: ...
