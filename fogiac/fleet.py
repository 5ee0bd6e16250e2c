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


def ensure_edge_master(plan: Plan, uri: str, *, start: bool) -> None:
    """The edge's ROS master must answer; for demos fogiac can run it (supervised, stopped by down)."""
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
    return f"{access.address}:{next(r.port for r in plan.relay if r.host == host)}"


def provision_and_connect(plan: Plan, *, access: Mapping[str, Any], connect: Mapping[str, str], master: str,
                          started_edge_master: bool = False,
                          progress: Callable[[str, str, str], None] | None = None) -> FleetUp:
    """Provision every host, start one edge relay per host that came up, record the deployment.

    Every target ends here: ``local`` and ``hosts`` with their own access records, ``aws`` with
    the instances' addresses and pinned host keys. A failed host fails the run; the others stay
    up so ``fogiac down`` (or a fixed re-run) finds them.
    """
    from fogiac.certs import load_or_create_bundle
    from fogiac.provision import supervise
    from fogiac.provision.runner import provision

    folder = stack_dir(plan.stack)
    certs = folder / "certs"
    load_or_create_bundle(plan.stack, certs)
    report = provision(plan, hosts=access, state_dir=folder, certs_dir=certs, progress=progress)
    relays: dict[str, str] = {}
    for route in plan.relay:
        if not next(o for o in report.hosts if o.host == route.host).ok:
            continue
        relays[route.host] = connect[route.host]
        supervise.start(edge_dir(plan), f"relay-edge-{route.host}", _relay_argv(
            route, connect=relays[route.host], master=master, certs=certs,
            stats=edge_dir(plan) / f"relay-edge-{route.host}.stats.json"))
    deployment = folder / DEPLOYMENT_FILE
    write_json_atomic(deployment, {
        "target": plan.target, "edge_master": master, "relays": relays,
        "started_edge_master": started_edge_master, "nodes": {n.name: n.host for n in plan.nodes},
    })
    if not report.ok:
        lines = [f"{o.host}: {o.error}" for o in report.failed]
        raise ProvisionError("; ".join(lines) + " (the other hosts are up; `fogiac down` removes everything)")
    return FleetUp(report=report, relays=relays, edge_master=master, deployment=deployment)


def fleet_up(plan: Plan, opts: FleetOptions) -> FleetUp:
    """``up`` for local sandboxes and lab hosts: nothing to create, everything to provision."""
    from fogiac.provision.targets import access_for

    master = opts.edge_master or plan.edge_master
    if not opts.yes and not opts.confirm(f"Deploy {len(plan.nodes)} node(s) to {len(plan.hosts)} {plan.target} host(s)?"):
        raise FogiacError("not applied: nothing was changed")
    with stack_lock(plan.stack, operation="up"):
        ensure_edge_master(plan, master, start=opts.start_edge_master)
        access = access_for(plan, state_dir=stack_dir(plan.stack))
        connect = {host: _connect_address(plan, host, a) for host, a in access.items()}
        return provision_and_connect(plan, access=access, connect=connect, master=master,
                                     started_edge_master=opts.start_edge_master, progress=opts.progress)


def aws_access(plan: Plan, outputs: Mapping[str, Any], *, fingerprints: Callable[[str], tuple[str, ...]]
               ) -> tuple[dict[str, Any], dict[str, str]]:
    """SSH access (host keys pinned from each console) and relay addresses from the stack outputs.

    In vpn mode the edge reaches a host's private address through the Client VPN; in proxy mode
    its public address, which the security group opens to ``ssh_from`` only.
    """
    from fogiac.provision.host import SshAccess
    from stacks.entry import SSH_KEY

    key = stack_dir(plan.stack) / "ssh" / SSH_KEY
    hosts = outputs.get("compute", {}).get("hosts", {})
    access: dict[str, Any] = {}
    connect: dict[str, str] = {}
    for spec in plan.hosts:
        out = hosts.get(spec.name)
        if not out or not out.get("public_ip"):
            raise ProvisionError(f"host {spec.name}: the compute stack reported no public address")
        access[spec.name] = SshAccess(address=out["public_ip"], user="ubuntu", key=key,
                                      fingerprints=fingerprints(out["instance_id"]))
        route = next(r for r in plan.relay if r.host == spec.name)
        via = out["private_ip"] if route.connect_via == "private" else out["public_ip"]
        connect[spec.name] = f"{via}:{route.port}"
    return access, connect


def edge_services(plan: Plan) -> list[str]:
    folder = edge_dir(plan)
    return sorted(p.stem for p in folder.glob("*.pid")) if folder.exists() else []


def stop_edge(plan: Plan, *, keep_master: bool = False) -> None:
    """Stop this machine's edge processes of the stack: the relays, and the demo master unless kept."""
    from fogiac.provision import supervise

    names = [s for s in edge_services(plan) if not (keep_master and s == EDGE_MASTER)]
    if names:
        supervise.stop_many(edge_dir(plan), names)


def fleet_down(plan: Plan) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Stop the edge relays, tear every host down; return (errors, what is left)."""
    from fogiac.provision import supervise
    from fogiac.provision.runner import teardown
    from fogiac.provision.targets import access_for

    folder = stack_dir(plan.stack)
    errors: list[str] = []
    with stack_lock(plan.stack, operation="down"):
        stop_edge(plan, keep_master=True)
        try:
            report = teardown(plan, hosts=access_for(plan, state_dir=folder), state_dir=folder)
            errors += [f"{o.host}: {o.error}" for o in report.failed]
        except FogiacError as err:
            errors.append(str(err))
        stop_edge(plan)
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
