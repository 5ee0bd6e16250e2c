"""The robot's side of a stack on this machine, and the step every target ends ``up`` on.

Provision and connect: certificates, provisioning of every host in parallel, then the
middleware's edge end for each host that came up (one relay per host, or the edge router's
links), supervised from the stack's ``edge/`` folder. A target whose platform runs the nodes
itself skips the provisioning and goes straight to :func:`connect_edge`. Stopping them, and reading from their
stats files when the edge was last there, live here too.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fogiac.certs import load_or_create_edges
from fogiac.endpoint import Endpoint
from fogiac.errors import ProvisionError
from fogiac.net import middleware
from fogiac.plan.model import Plan
from fogiac.provision import provision, supervise
from fogiac.state import StackState, read_json

STATS_STALE_S = 30.0  # a relay writes its stats every second: this much older and it no longer runs


@dataclass(frozen=True)
class FleetUp:
    report: Any  # fogiac.provision.runner.ProvisionReport
    relays: Mapping[str, str]  # host -> HOST:PORT the edge relay connects to
    edge_master: str
    deployment: str  # where the record that now names the edge's links is kept
    notes: tuple[str, ...] = ()  # the middleware's lines for the user: files written, what to install


def edge_dir(plan: Plan, *, create: bool = True) -> Path:
    state = StackState(plan.stack)
    if create:
        state.ensure()
    return state.edge


def ensure_edge_master(plan: Plan, uri: str, *, start: bool) -> None:
    """The robot's side must be there before anything is provisioned (the middleware says what that means)."""
    middleware.deployment(plan.middleware).prepare_edge(plan, uri, folder=edge_dir(plan), start=start)


def dialed_addresses(connect: Mapping[str, str]) -> dict[str, str]:
    """host -> the address alone, from ``connect``'s ``HOST:PORT`` (``[v6]:PORT`` too)."""
    return {host: Endpoint.parse(address).host for host, address in connect.items()}


def provision_and_connect(plan: Plan, *, access: Mapping[str, Any], connect: Mapping[str, str], master: str,
                          started_edge_master: bool = False,
                          progress: Callable[[str, str, str], None] | None = None,
                          ports: Mapping[str, Any] | None = None, provisions: bool = True) -> FleetUp:
    """Provision every host, start the middleware's edge side for the hosts that came up, record the deployment.

    Every target ends ``up`` here. One that provisions (``Feature.PROVISIONS``): ``local`` and ``hosts``
    with their own access records, a cloud with its instances' addresses and pinned host keys. A failed
    host fails the run; the others stay up so ``fogiac down`` (or a fixed re-run) finds them. One whose
    platform runs the nodes and their end of the link (``provisions=False``) answered ``connect`` itself:
    nothing is provisioned, and only the edge's end starts (:func:`connect_edge`).
    """
    if not provisions:
        return connect_edge(plan, connect=connect, master=master, started_edge_master=started_edge_master)
    state = StackState(plan.stack)
    folder, certs = state.ensure(), state.certs
    load_or_create_edges(plan.stack, certs, [edge.named for edge in plan.edges])  # the CA's, and each edge's
    forget_dropped_revocations(plan)
    report = provision(plan, hosts=access, state_dir=folder, certs_dir=certs, progress=progress,
                       dialed=dialed_addresses(connect), ports=ports)
    relays = {o.host: connect[o.host] for o in report.hosts if o.ok and o.host in connect}
    done = connect_edge(plan, connect=relays, master=master, started_edge_master=started_edge_master, report=report)
    if not report.ok:
        lines = [o.error or f"{o.host}: failed" for o in report.failed]
        raise ProvisionError("; ".join(lines) + " (the other hosts are up; `fogiac down` removes everything)")
    return done


def forget_dropped_revocations(plan: Plan) -> None:
    """A robot revoked by hand stays revoked until restored or dropped from the manifest: once ``robots:`` no
    longer lists it, the record forgets it, so a robot of that name added later starts unrevoked."""
    state = StackState(plan.stack)
    revoked = state.get(StackState.REVOKED)
    if not isinstance(revoked, list):
        return
    robots = {edge.name for edge in plan.edges} if plan.fleet else set()
    kept = [name for name in revoked if name in robots]
    if kept != revoked:
        state.update(lambda document: document.__setitem__(StackState.REVOKED, kept) if kept
                     else document.pop(StackState.REVOKED, None))


def connect_edge(plan: Plan, *, connect: Mapping[str, str], master: str, started_edge_master: bool = False,
                 report: Any = None) -> FleetUp:
    """Start the middleware's edge side for the hosts in ``connect`` (host -> HOST:PORT) and record the
    deployment: after provisioning, or straight away for a target whose platform runs the nodes and the
    host's end itself (it answered ``connect`` on its own)."""
    state = StackState(plan.stack)
    state.ensure()
    certs = state.certs
    relays = dict(connect)
    notes = middleware.deployment(plan.middleware).edge_up(plan, entry=master, connect=relays, certs=certs,
                                                           folder=edge_dir(plan)) if relays else []
    record_edge(plan, {"target": plan.target, "edge_master": master, "relays": relays,
                       "started_edge_master": started_edge_master, "nodes": {n.name: n.host for n in plan.nodes}})
    deployment = state.where()
    return FleetUp(report=report, relays=relays, edge_master=master, deployment=deployment, notes=tuple(notes))


def edge_name(plan: Plan) -> str:
    """The identity of the edge ``edge_master`` names, the plan's first (today's manifests have one, named
    after the stack)."""
    return plan.edges[0].name


def record_edge(plan: Plan, links: Mapping[str, Any]) -> None:
    """Record the plan's edges in the record's list, each with its identity, its entry (the first edge's as
    ``links`` says, which a ``--edge-master`` may have overridden; the others' their own), its links host ->
    HOST:PORT and the nodes; an edge of the same identity is replaced, any other kept."""
    mine = [{"name": edge.name, **links, **({} if i == 0 else {"edge_master": edge.entry})}
            for i, edge in enumerate(plan.edges)]
    names = {edge["name"] for edge in mine}

    def change(document: dict[str, Any]) -> None:
        edges = document.get(StackState.EDGES)
        others = [e for e in edges if not (isinstance(e, Mapping) and e.get("name") in names)] \
            if isinstance(edges, list) else []
        document[StackState.EDGES] = [*others, *mine]

    StackState(plan.stack).update(change)


def recorded_edge(plan: Plan) -> dict[str, Any]:
    """The stack's edge as the last ``up`` recorded it (``{}`` when none is)."""
    edges = StackState(plan.stack).get(StackState.EDGES)
    name = edge_name(plan)
    found = [e for e in edges if isinstance(e, Mapping) and e.get("name") == name] if isinstance(edges, list) else []
    return dict(found[0]) if found else {}


def edge_services(plan: Plan) -> list[str]:
    folder = StackState(plan.stack).edge  # asking creates nothing
    return sorted(p.stem for p in folder.glob("*.pid")) if folder.exists() else []


def running_edge(plan: Plan) -> list[dict[str, Any]]:
    """The stack's edge processes on this machine that still run, with their pids."""
    return [s for s in (supervise.status(edge_dir(plan, create=False), name) for name in edge_services(plan))
            if s["running"]]


def edge_status(plan: Plan) -> dict[str, Any]:
    """The edge's part of ``status``: its master as the last ``up`` recorded it (``edge_master``), each link as
    its middleware reads it from the edge's stats (``relays``), and its processes still running here (``edge``)."""
    saved = recorded_edge(plan)
    relays = middleware.deployment(plan.middleware).edge_links(plan, folder=edge_dir(plan, create=False),
                                                               connect=saved.get("relays", {}))
    return {"edge_master": saved.get("edge_master", plan.edge_master), "relays": relays, "edge": running_edge(plan)}


def edge_idle_since(plan: Plan, *, now: float) -> float | None:
    """Since when no edge link of the stack has run on this machine, from the stats files its
    middleware names (:meth:`fogiac.net.middleware.Deployment.edge_stats`).

    A running link rewrites its stats every second: a fresh file that says connected means an
    edge is there now (None); a stale one dates the link's last breath. A fresh file that says
    disconnected cannot be dated, nor can a link this machine never ran: None, unknown.
    """
    last: list[float] = []
    for path in middleware.deployment(plan.middleware).edge_stats(plan, folder=edge_dir(plan)):
        try:
            written = path.stat().st_mtime
        except OSError:
            continue
        if now - written >= STATS_STALE_S:
            last.append(written)
        elif (read_json(path) or {}).get("connected"):
            return None
    return max(last) if last else None


def wake_robot(plan: Plan, robot: str) -> list[str]:
    """Restored: ``robot``'s edge processes on this machine dial now (its middleware's, none elsewhere)."""
    folder = edge_dir(plan, create=False)
    return middleware.wake_robot(plan.middleware, plan, robot, folder=folder) if folder.exists() else []


def stop_edge(plan: Plan, *, keep_master: bool = False) -> None:
    """Stop this machine's edge processes of the stack: the links, and what stands in for the robot's
    graph (the demo's master) unless kept."""
    kept = middleware.deployment(plan.middleware).robot_side if keep_master else ()
    names = [s for s in edge_services(plan) if s.partition("@")[0] not in kept]  # every edge's ("NAME@edge")
    if names:
        supervise.stop_many(edge_dir(plan), names)
