"""The robot's side of a stack on this machine, and the step every target ends ``up`` on.

Provision and connect: certificates, provisioning of every host in parallel, then the
middleware's edge end for each host that came up (one relay per host, or the edge router's
links), supervised from the stack's ``edge/`` folder. Stopping them, and reading from their
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

DEPLOYMENT_FILE = StackState.DEPLOYMENT
STATS_STALE_S = 30.0  # a relay writes its stats every second: this much older and it no longer runs


@dataclass(frozen=True)
class FleetUp:
    report: Any  # fogiac.provision.runner.ProvisionReport
    relays: Mapping[str, str]  # host -> HOST:PORT the edge relay connects to
    edge_master: str
    deployment: Path
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
                          progress: Callable[[str, str, str], None] | None = None) -> FleetUp:
    """Provision every host, start the middleware's edge side for the hosts that came up, record the deployment.

    Every target ends here: ``local`` and ``hosts`` with their own access records, a cloud with
    its instances' addresses and pinned host keys. A failed host fails the run; the others stay
    up so ``fogiac down`` (or a fixed re-run) finds them.
    """
    state = StackState(plan.stack)
    folder, certs = state.ensure(), state.certs
    load_or_create_edges(plan.stack, certs, [edge.named for edge in plan.edges])  # the CA's, and each edge's
    report = provision(plan, hosts=access, state_dir=folder, certs_dir=certs, progress=progress,
                       dialed=dialed_addresses(connect))
    relays = {o.host: connect[o.host] for o in report.hosts if o.ok and o.host in connect}
    notes = middleware.deployment(plan.middleware).edge_up(plan, entry=master, connect=relays, certs=certs,
                                                           folder=edge_dir(plan)) if relays else []
    deployment = state.write(DEPLOYMENT_FILE, {
        "target": plan.target, "edge_master": master, "relays": relays,
        "started_edge_master": started_edge_master, "nodes": {n.name: n.host for n in plan.nodes},
    })
    if not report.ok:
        lines = [o.error or f"{o.host}: failed" for o in report.failed]
        raise ProvisionError("; ".join(lines) + " (the other hosts are up; `fogiac down` removes everything)")
    return FleetUp(report=report, relays=relays, edge_master=master, deployment=deployment, notes=tuple(notes))


def edge_services(plan: Plan) -> list[str]:
    folder = StackState(plan.stack).edge  # asking creates nothing
    return sorted(p.stem for p in folder.glob("*.pid")) if folder.exists() else []


def running_edge(plan: Plan) -> list[dict[str, Any]]:
    """The stack's edge processes on this machine that still run, with their pids."""
    return [s for s in (supervise.status(edge_dir(plan, create=False), name) for name in edge_services(plan))
            if s["running"]]


def edge_idle_since(plan: Plan, *, now: float) -> float | None:
    """Since when no edge relay of the stack has run on this machine, from their stats files.

    A running relay rewrites its stats every second: a fresh file that says connected means an
    edge is there now (None); a stale one dates the relay's last breath. A fresh file that says
    disconnected cannot be dated, nor can a relay this machine never ran: None, unknown.
    """
    last: list[float] = []
    for route in plan.routes:
        path = edge_dir(plan) / f"relay-edge-{route.host}.stats.json"
        try:
            written = path.stat().st_mtime
        except OSError:
            continue
        if now - written >= STATS_STALE_S:
            last.append(written)
        elif (read_json(path) or {}).get("connected"):
            return None
    return max(last) if last else None


def stop_edge(plan: Plan, *, keep_master: bool = False) -> None:
    """Stop this machine's edge processes of the stack: the links, and what stands in for the robot's
    graph (the demo's master) unless kept."""
    kept = middleware.deployment(plan.middleware).robot_side if keep_master else ()
    names = [s for s in edge_services(plan) if s.partition("@")[0] not in kept]  # every edge's ("NAME@edge")
    if names:
        supervise.stop_many(edge_dir(plan), names)
