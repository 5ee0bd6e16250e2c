"""``up`` and ``down`` for machines fogiac does not create: ``local`` sandboxes and ``hosts``.

Up: certificates, (optionally) the edge's ROS master for a demo, provisioning of every host in
parallel, then one edge relay per host, supervised, joining the edge master to that host's
master over mutual TLS. Down undoes each of these and then proves it: no supervised process
alive, no sandbox left. Everything lives in the stack's state folder.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

from fogiac.errors import FogiacError, ProvisionError
from fogiac.plan import Plan, RelayRoute
from fogiac.state import read_json, stack_dir, stack_lock, write_json_atomic

DEPLOYMENT_FILE = "deployment.json"
EDGE_DIR = "edge"
EDGE_MASTER = "edge-master"


@dataclass(frozen=True)
class FleetOptions:
    yes: bool = False
    start_edge_master: bool = False  # the demo's edge: fogiac runs the robot-side roscore too
    edge_master: str | None = None  # overrides the manifest's edge.ros_master
    confirm: Callable[[str], bool] = lambda question: False
    progress: Callable[[str, str, str], None] | None = None  # provisioning's (host, step, status)


@dataclass(frozen=True)
class FleetUp:
    report: Any  # fogiac.provision.runner.ProvisionReport
    relays: Mapping[str, str]  # host -> HOST:PORT the edge relay connects to
    edge_master: str
    deployment: Path


def edge_dir(plan: Plan) -> Path:
    return stack_dir(plan.stack) / EDGE_DIR


def _relay_argv(route: RelayRoute, *, connect: str, master: str, certs: Path, stats: Path) -> list[str]:
    argv = [sys.executable, "-m", "fogiac", "relay", "edge", "--connect", connect, "--master", master,
            "--certs", str(certs), "--stats-file", str(stats), "--queue-depth", str(route.queue_size)]
    # The manifest's "in" (robot -> node) is what the edge sends out, its "out" what comes in.
    if route.to_cloud:
        argv += ["--out", ",".join(route.to_cloud)]
    if route.to_edge:
        argv += ["--in", ",".join(route.to_edge)]
    argv += ["--topics", "auto" if route.auto else ",".join(route.listed)] if (route.auto or route.listed) else []
    compression = dict(route.compression)
    if "*" in compression:
        argv += ["--compression", compression["*"]]
    elif compression:
        argv += ["--compression", ",".join(f"{t}={alg}" for t, alg in sorted(compression.items()))]
    return argv


def _master_up(uri: str, *, timeout: float) -> bool:
    import xmlrpc.client

    deadline = time.monotonic() + timeout
    while True:
        try:
            code, _, _ = xmlrpc.client.ServerProxy(uri).getPid("/fogiac")
            if code == 1:
                return True
        except (OSError, xmlrpc.client.Error):
            pass
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.2)


def _ensure_edge_master(plan: Plan, uri: str, *, start: bool) -> None:
    from fogiac.provision import supervise

    if _master_up(uri, timeout=0.5):
        return
    if not start:
        raise FogiacError(f"no ROS master answers at {uri} (edge.ros_master); start roscore, "
                          "or pass --start-edge-master to let fogiac run one")
    url = urlparse(uri)
    supervise.start(edge_dir(plan), EDGE_MASTER, ["roscore", "-p", str(url.port)])
    if not _master_up(uri, timeout=30):
        supervise.stop(edge_dir(plan), EDGE_MASTER)
        raise FogiacError(f"the edge roscore did not come up at {uri}; see {edge_dir(plan) / (EDGE_MASTER + '.log')}")


def _connect_address(plan: Plan, host: str, access: Any) -> str:
    if access.kind == "local":
        return f"127.0.0.1:{access.relay_port}"
    return f"{access.address}:{plan.relay[[r.host for r in plan.relay].index(host)].port}"


def fleet_up(plan: Plan, opts: FleetOptions) -> FleetUp:
    """Provision every host, then start the edge relays; a failed host fails the run, others stay up."""
    from fogiac.certs import load_or_create_bundle
    from fogiac.provision import supervise
    from fogiac.provision.runner import provision
    from fogiac.provision.targets import access_for

    folder = stack_dir(plan.stack)
    master = opts.edge_master or plan.edge_master
    if not opts.yes and not opts.confirm(f"Deploy {len(plan.nodes)} node(s) to {len(plan.hosts)} {plan.target} host(s)?"):
        raise FogiacError("not applied: nothing was changed")
    with stack_lock(plan.stack, operation="up"):
        _ensure_edge_master(plan, master, start=opts.start_edge_master)
        certs = folder / "certs"
        load_or_create_bundle(plan.stack, certs)
        access = access_for(plan, state_dir=folder)
        report = provision(plan, hosts=access, state_dir=folder, certs_dir=certs, progress=opts.progress)
        relays: dict[str, str] = {}
        for route in plan.relay:
            outcome = next(o for o in report.hosts if o.host == route.host)
            if not outcome.ok:
                continue
            relays[route.host] = _connect_address(plan, route.host, access[route.host])
            supervise.start(edge_dir(plan), f"relay-edge-{route.host}", _relay_argv(
                route, connect=relays[route.host], master=master, certs=certs,
                stats=edge_dir(plan) / f"relay-edge-{route.host}.stats.json"))
        deployment = folder / DEPLOYMENT_FILE
        write_json_atomic(deployment, {
            "target": plan.target, "edge_master": master, "relays": relays,
            "started_edge_master": opts.start_edge_master,
            "nodes": {n.name: n.host for n in plan.nodes},
        })
        if not report.ok:
            lines = [f"{o.host}: {o.error}" for o in report.failed]
            raise ProvisionError("; ".join(lines) + " (the other hosts are up; `fogiac down` removes everything)")
        return FleetUp(report=report, relays=relays, edge_master=master, deployment=deployment)


def edge_services(plan: Plan) -> list[str]:
    folder = edge_dir(plan)
    return sorted(p.stem for p in folder.glob("*.pid")) if folder.exists() else []


def fleet_down(plan: Plan) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Stop the edge relays, tear every host down; return (errors, what is left)."""
    from fogiac.provision import supervise
    from fogiac.provision.runner import teardown
    from fogiac.provision.targets import access_for

    folder = stack_dir(plan.stack)
    errors: list[str] = []
    with stack_lock(plan.stack, operation="down"):
        supervise.stop_many(edge_dir(plan), [s for s in edge_services(plan) if s != EDGE_MASTER])
        try:
            report = teardown(plan, hosts=access_for(plan, state_dir=folder), state_dir=folder)
            errors += [f"{o.host}: {o.error}" for o in report.failed]
        except FogiacError as err:
            errors.append(str(err))
        supervise.stop_many(edge_dir(plan), edge_services(plan))
        left = [f"process {name} (pid {supervise.status(edge_dir(plan), name)['pid']})"
                for name in edge_services(plan) if supervise.status(edge_dir(plan), name)["running"]]
        if plan.target == "local":
            from fogiac.provision.local import sandbox_root

            left += [f"sandbox {p}" for p in sorted(sandbox_root(folder).glob("*")) if p.is_dir()]
        if not left and not errors:
            (folder / DEPLOYMENT_FILE).unlink(missing_ok=True)
    return tuple(errors), tuple(left)


def fleet_status(plan: Plan) -> dict[str, Any]:
    """Hosts, nodes (running, restarts) and relayed topics with live figures, from the state folder."""
    from fogiac.provision import supervise
    from fogiac.provision.runner import recorded_access

    folder = stack_dir(plan.stack, create=False)
    deployment = read_json(folder / DEPLOYMENT_FILE) if folder.exists() else None
    if not deployment:
        return {"deployed": False, "hosts": [], "relays": []}
    recorded = recorded_access(folder)
    hosts = []
    for spec in plan.hosts:
        entry = recorded.get(spec.name)
        services = []
        if entry is not None and plan.target == "local":
            run_dir = Path(entry[1]) / "run"
            for node in spec.nodes:
                services.append({"node": node, **supervise.status(run_dir, f"node-{node}")})
        hosts.append({"host": spec.name, "machine": spec.machine, "nodes": services or [{"node": n} for n in spec.nodes]})
    relays = []
    for host, connect in sorted(deployment.get("relays", {}).items()):
        stats = read_json(edge_dir(plan) / f"relay-edge-{host}.stats.json") or {}
        relays.append({"host": host, "connect": connect, **stats})
    return {"deployed": True, "edge_master": deployment.get("edge_master"), "hosts": hosts, "relays": relays}
