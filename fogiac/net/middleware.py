"""Middleware: how ROS traffic crosses between the robot and the cloud hosts, one registry.

::

    relay/   ROS 1 (noetic): fogiac's relay, TCPROS bytes over one mutual-TLS link the edge opens
    zenoh/   ROS 2 (humble, jazzy, kilted): a Zenoh router per cloud host (mutual TLS, per-topic
             access control) and an edge router that dials out to them

The ROS distribution picks the middleware (:func:`for_distro`). A variant is one folder with two
halves: its :class:`Middleware` (what compile, the targets' firewalls, plan, cost and graph ask: its
port and its words) and its :class:`Deployment` (what ``up``, ``down`` and provisioning ask), both
named by the :class:`~fogiac.middlewares.MiddlewareEntry` it publishes under the ``fogiac.middlewares``
entry point group. The halves load apart, so compiling never imports provisioning, certificates or
templates. Nothing else in fogiac names a variant; another installed package can add one, serving a ROS
distribution fogiac does not list and owning a top-level manifest block named after it
(:attr:`Middleware.block`), whose validated settings reach its deployment as ``Plan.middleware_settings``.
The table itself is :mod:`fogiac.middlewares` (neutral: the manifest asks it which middleware a
distribution picks, what its block is); this module adds what the layers above the manifest ask.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, cast

from fogiac import middlewares
from fogiac.hostmodel import Launching as Launching  # re-exported: what a middleware answers
from fogiac.hostmodel import NativeRos as NativeRos
from fogiac.middlewares import MiddlewareEntry as MiddlewareEntry  # re-exported: what a middleware publishes
from fogiac.middlewares import block_model as block_model  # re-exported: the table's questions, asked here too
from fogiac.middlewares import distros as distros

if TYPE_CHECKING:
    from fogiac.hostmodel import Service, Where
    from fogiac.plan.model import HostSpec, Plan
    from fogiac.provision.host import Host


class Middleware(middlewares.MiddlewareFacts, Protocol):
    """What the rest of fogiac may know about a middleware (the manifest's part: :class:`MiddlewareFacts`)."""

    @property
    def port(self) -> int: ...  # the TCP port the edge dials on each cloud host

    @property
    def label(self) -> str: ...  # one line for plan, cost and graph: what crosses and how

    @property
    def edge_side(self) -> str: ...  # what runs on the robot's side

    @property
    def cloud_side(self) -> str: ...  # what runs on each cloud host

    @property
    def rule_description(self) -> str: ...  # the security-group rule's description for ``port``

    @property
    def credentials_first(self) -> bool: ...  # True: host_credentials before host_services start, else at link

    @property
    def node_master(self) -> bool: ...  # True: nodes register with a ROS master, which health checks ask

    @property
    def nodes_after(self) -> str: ...  # the host service a node's unit starts after (its master or router)

    @property
    def host_requirements(self) -> tuple[str, ...]: ...  # pinned PyPI packages its cloud side imports on a host

    @property
    def launching(self) -> Launching: ...  # how its ROS generation builds a workspace and runs a launch file

    def edge_entry(self, edge: Any) -> str:
        """What the robot's side is reached at (``Plan.edge_master``): a master URI, a router endpoint,
        read from the manifest's ``edge:`` block (typed ``Any``: the manifest is imported by no middleware)."""
        ...


class Deployment(Protocol):
    """How a middleware is deployed: provisioning asks for a host's services, ``up``/``down``/``status``
    for the edge's."""

    def node_env(self, where: Where) -> Mapping[str, str]:
        """The environment every node on a host gets (its env file, its containers)."""
        ...

    def native_ros(self, distro: str) -> NativeRos:
        """What a host on the native runtime needs before this middleware's nodes can run there."""
        ...

    def host_services(self, plan: Plan, spec: HostSpec, where: Where, *, certs: Path | None) -> tuple[Service, ...]:
        """What the host's nodes need running before them (a ROS master, a router); ``certs``: the
        stack's CA folder on this machine."""
        ...

    def link_services(self, plan: Plan, spec: HostSpec, where: Where) -> tuple[Service, ...]:
        """What joins the host to the edge after its nodes run (empty when host_services does it)."""
        ...

    def link_files(self) -> tuple[tuple[str, int], ...]:
        """Files of the stack's certificate folder the link services read from the host's certs folder."""
        ...

    @property
    def link_program(self) -> str:
        """The file of fogiac's code (relative to the folder holding the ``fogiac`` package) its link
        services run: provisioning's probe looks for it on the host, and a host without it gets the link
        services' scripts only, not started. Empty when it has no link services."""
        ...

    def host_credentials(self, host: Host, *, python: str, folder: str, certs_dir: Path, plan: Plan,
                         spec: HostSpec, dialed: str) -> bool:
        """Credentials made on the host itself (its private key never leaves it); True when they changed.
        ``dialed``: the address the edge reaches the host at (what a certificate may have to name)."""
        ...

    def prepare_edge(self, plan: Plan, entry: str, *, folder: Path, start: bool) -> None:
        """Before provisioning: the robot's side must be there (or fogiac starts it, for demos)."""
        ...

    def edge_up(self, plan: Plan, *, entry: str, connect: Mapping[str, str], certs: Path,
                folder: Path) -> list[str]:
        """Start this machine's edge processes (supervised under ``folder``) for the hosts in
        ``connect`` (host -> HOST:PORT); returns lines for the user (files written, what to install)."""
        ...

    def edge_links(self, plan: Plan, *, folder: Path, connect: Mapping[str, str]) -> list[dict[str, Any]]:
        """Per host: ``{host, connect, connected, rtt_ms?, topics: [{topic, direction, msgs, ...}]}``."""
        ...

    def edge_stats(self, plan: Plan, *, folder: Path) -> tuple[Path, ...]:
        """The stats files its edge link processes under ``folder`` rewrite while they run, each a JSON
        object whose ``connected`` says whether that link is up: what dates the edge's last link
        (:func:`fogiac.lifecycle.edge.edge_idle_since`). Empty where the edge's files cannot say."""
        ...

    @property
    def robot_side(self) -> tuple[str, ...]:
        """Edge services that stand in for the robot's own ROS graph (a demo's roscore): ``down`` stops
        them after the links and the hosts, so nothing of the robot's graph goes first."""
        ...


def deploys_fleet(name: str) -> bool:
    """Whether ``up`` can deploy a fleet (``robots:``) over middleware ``name``: its deployment says so with
    ``deploys_fleet = True`` and answers :func:`fleet_files`. Optional, so a plug-in written before fleets
    keeps working for one robot and is refused a fleet in one line."""
    return bool(getattr(deployment(name), "deploys_fleet", False))


def fleet_files(name: str, plan: Plan, spec: HostSpec, *,
                revoked: tuple[str, ...]) -> tuple[tuple[str, bytes, int], ...]:
    """The files (name, bytes, mode) a fleet's host keeps beside its link's certificates: who may link and
    for which topics (the relay's ``fleet.json``), with the record's ``revoked`` robots refused. The link
    reads them again when they change: provisioning rewrites them and restarts nothing. Empty for one robot
    and for a middleware that deploys no fleet."""
    made = getattr(deployment(name), "fleet_files", None)
    return tuple(made(plan, spec, revoked=revoked)) if made is not None else ()


def wake_robot(name: str, plan: Plan, robot: str, *, folder: Path) -> list[str]:
    """Make a restored robot's edge processes on this machine link now rather than at the end of the wait its
    refusals made (``fogiac robot restore``); returns what was woken. Optional, as :func:`fleet_files` is: a
    middleware whose edge does not back off on refusal has nothing to wake."""
    wake = getattr(deployment(name), "wake_robot", None)
    return list(wake(plan, robot, folder=folder)) if wake is not None else []


def register(middleware: Middleware, deployment: Deployment) -> Middleware:
    """Add (or replace) a middleware for this process (tests, embedders); returns it."""
    middlewares.DEPLOYMENTS.register(middleware.name, deployment)
    return middlewares.FACTS.register(middleware.name, middleware)


def unregister(name: str) -> None:
    middlewares.FACTS.unregister(name)
    middlewares.DEPLOYMENTS.unregister(name)


def names() -> tuple[str, ...]:
    return middlewares.names()


def get(name: str) -> Middleware:
    found: Middleware = middlewares.FACTS.get(name)
    return found


def deployment(name: str) -> Deployment:
    """How ``name`` is deployed (imported on first use: see the module docstring)."""
    found: Deployment = middlewares.DEPLOYMENTS.get(name)
    return found


def for_distro(distro: str) -> Middleware:
    """The middleware that serves ROS ``distro``; an unknown one fails listing those served."""
    return cast(Middleware, middlewares.for_distro(distro))  # FACTS holds whole Middlewares
