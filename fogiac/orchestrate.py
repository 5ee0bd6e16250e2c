"""Provision and connect, the path every target ends on; and the base of targets whose
machines already exist (``local`` sandboxes, ``hosts``).

Up: certificates, (optionally) the edge's ROS master for a demo, provisioning of every host in
parallel, then one edge relay per host, supervised, joining the edge master to that host's
master over mutual TLS. Down undoes each of these and then proves it: no supervised process
alive, nothing of the target left. Everything lives in the stack's state folder.
"""

from __future__ import annotations

import re
import sys
import xmlrpc.client
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

from fogiac.certs import load_or_create_bundle
from fogiac.errors import FogiacError, ProvisionError
from fogiac.plan.model import HostSpec, Plan, RelayRoute
from fogiac.procs import poll
from fogiac.provision import HostAccess, provision, recorded_access, supervise, teardown
from fogiac.state import read_json, stack_dir, stack_lock, write_json_atomic
from fogiac.tables import table
from fogiac.targets.base import DownOptions, DownResult, Refreshed, SweepOutcome, UpOptions, UpResult

DEPLOYMENT_FILE = "deployment.json"
EDGE_DIR = "edge"
EDGE_MASTER = "edge-master"


@dataclass(frozen=True)
class FleetUp:
    report: Any  # fogiac.provision.runner.ProvisionReport
    relays: Mapping[str, str]  # host -> HOST:PORT the edge relay connects to
    edge_master: str
    deployment: Path


def edge_dir(plan: Plan) -> Path:
    return stack_dir(plan.stack) / EDGE_DIR


def _relay_argv(route: RelayRoute, *, stack: str, connect: str, master: str, certs: Path, stats: Path) -> list[str]:
    # One ROS name per relay: a master drops a node when another registers with its name, so
    # the relays of several hosts (or several stacks) on one edge master would evict each other.
    name = "/fogiac_relay_edge_" + re.sub(r"[^A-Za-z0-9_]", "_", f"{stack}_{route.host}")
    argv = [sys.executable, "-m", "fogiac", "relay", "edge", "--connect", connect, "--master", master,
            "--certs", str(certs), "--stats-file", str(stats), "--queue-depth", str(route.queue_size),
            "--name", name]
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
    def answers() -> bool | None:
        try:
            reply: Any = xmlrpc.client.ServerProxy(uri).getPid("/fogiac")
        except (OSError, xmlrpc.client.Error):
            return None
        return True if reply[0] == 1 else None

    return poll(answers, timeout=timeout, interval=0.2, backoff=1.0) is not None


def ensure_edge_master(plan: Plan, uri: str, *, start: bool) -> None:
    """The edge's ROS master must answer; for demos fogiac can run it (supervised, stopped by down)."""
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


def provision_and_connect(plan: Plan, *, access: Mapping[str, Any], connect: Mapping[str, str], master: str,
                          started_edge_master: bool = False,
                          progress: Callable[[str, str, str], None] | None = None) -> FleetUp:
    """Provision every host, start one edge relay per host that came up, record the deployment.

    Every target ends here: ``local`` and ``hosts`` with their own access records, ``aws`` with
    the instances' addresses and pinned host keys. A failed host fails the run; the others stay
    up so ``fogiac down`` (or a fixed re-run) finds them.
    """
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
            route, stack=plan.stack, connect=relays[route.host], master=master, certs=certs,
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


def edge_services(plan: Plan) -> list[str]:
    folder = edge_dir(plan)
    return sorted(p.stem for p in folder.glob("*.pid")) if folder.exists() else []


def stop_edge(plan: Plan, *, keep_master: bool = False) -> None:
    """Stop this machine's edge processes of the stack: the relays, and the demo master unless kept."""
    names = [s for s in edge_services(plan) if not (keep_master and s == EDGE_MASTER)]
    if names:
        supervise.stop_many(edge_dir(plan), names)




class ExistingMachines:
    """The base of targets whose machines exist already (``local`` sandboxes, ``hosts``).

    Nothing to create, everything to provision: ``up`` asks, starts (or checks) the edge
    master, provisions every host and connects one edge relay per host; ``down`` undoes it and
    proves it. A subclass says how to reach each host (:meth:`access`), which address the edge
    relay dials (:meth:`connect_address`), what of its own could be left (:meth:`leftovers`)
    and how to read a host's node states (:meth:`node_states`).
    """

    name = ""
    summary = ""
    makes_resources = False
    no_cloud = "has no cloud account: nothing to {verb}"

    def access(self, plan: Plan, *, state_dir: Path) -> Mapping[str, HostAccess]:
        raise NotImplementedError

    def connect_address(self, plan: Plan, host: str, access: HostAccess) -> str:
        return f"{access.address}:{next(r.port for r in plan.relay if r.host == host)}"  # type: ignore[attr-defined]

    def leftovers(self, plan: Plan, folder: Path) -> list[str]:
        return []

    def node_states(self, plan: Plan, spec: HostSpec, entry: Any) -> list[dict[str, Any]]:
        return [{"node": n} for n in spec.nodes]

    def declare(self, plan: Plan) -> tuple[Mapping[str, Any], ...]:
        return ()  # nothing is created: the machines exist

    def up(self, plan: Plan, opts: UpOptions) -> UpResult:
        master = opts.edge_master or plan.edge_master
        question = f"Deploy {len(plan.nodes)} node(s) to {len(plan.hosts)} {plan.target} host(s)?"
        if not opts.yes and not opts.confirm(question):
            raise FogiacError("not applied: nothing was changed")
        with stack_lock(plan.stack, operation="up"):
            ensure_edge_master(plan, master, start=opts.start_edge_master)
            access = self.access(plan, state_dir=stack_dir(plan.stack))
            connect = {host: self.connect_address(plan, host, a) for host, a in access.items()}
            done = provision_and_connect(plan, access=access, connect=connect, master=master,
                                         started_edge_master=opts.start_edge_master)
        return UpResult(outputs={"relays": dict(done.relays)}, applied=done.deployment, report=done.report,
                        relays=done.relays, edge_master=master)

    def down(self, plan: Plan, opts: DownOptions) -> DownResult:
        """Stop the edge relays, tear every host down, then prove nothing is left."""
        folder = stack_dir(plan.stack)
        errors: list[str] = []
        with stack_lock(plan.stack, operation="down"):
            stop_edge(plan, keep_master=True)
            try:
                report = teardown(plan, hosts=self.access(plan, state_dir=folder), state_dir=folder)
                errors += [f"{o.host}: {o.error}" for o in report.failed]
            except FogiacError as err:
                errors.append(str(err))
            stop_edge(plan)
            left = [f"process {name} (pid {supervise.status(edge_dir(plan), name)['pid']})"
                    for name in edge_services(plan) if supervise.status(edge_dir(plan), name)["running"]]
            left += self.leftovers(plan, folder)
            if not left and not errors:
                (folder / DEPLOYMENT_FILE).unlink(missing_ok=True)
        return DownResult(engine_errors=tuple(errors), left=tuple(left), not_checked=())

    def status(self, plan: Plan) -> dict[str, Any]:
        """Hosts, nodes (running, restarts) and relayed topics with live figures, from the state folder."""
        head = {"stack": plan.stack, "target": plan.target}
        folder = stack_dir(plan.stack, create=False)
        deployment = read_json(folder / DEPLOYMENT_FILE) if folder.exists() else None
        if not deployment:
            return {**head, "deployed": False, "hosts": [], "relays": []}
        recorded = recorded_access(folder)
        hosts = [{"host": spec.name, "machine": spec.machine,
                  "nodes": self.node_states(plan, spec, recorded.get(spec.name))} for spec in plan.hosts]
        relays = []
        for host, connect in sorted(deployment.get("relays", {}).items()):
            stats = read_json(edge_dir(plan) / f"relay-edge-{host}.stats.json") or {}
            relays.append({"host": host, "connect": connect, **stats})
        return {**head, "deployed": True, "edge_master": deployment.get("edge_master"), "hosts": hosts,
                "relays": relays}

    def render_status(self, doc: Mapping[str, Any]) -> list[Any]:
        """Nodes with their supervision state, then relayed topics with live figures."""
        if not doc.get("deployed"):
            return [f"{doc['stack']}: not deployed"]
        nodes = table(f"{doc['stack']} ({doc['target']}), edge {doc.get('edge_master')}",
                      "host", "machine", "node", "state", "restarts")
        for host in doc["hosts"]:
            for node in host["nodes"]:
                state = "-" if "running" not in node else "running" if node["running"] else "failed"
                nodes.add_row(host["host"], host["machine"], node["node"], state, str(node.get("restarts", "-")))
        relays = table("relayed topics", "host", "link", "topic", "dir", "msgs", "msgs/s", "KiB/s", "latency ms",
                       "drops")
        for relay in doc["relays"]:
            rtt = f" {relay['rtt_ms']:.2f} ms" if relay.get("rtt_ms") else ""
            link = ("up" if relay.get("connected") else "down") + rtt
            for t in relay.get("topics", []) or [{}]:
                latency = "-" if t.get("latency_ms") is None else f"{t['latency_ms']:.2f}"
                rate = t.get("bytes_per_s")
                relays.add_row(relay["host"], link, t.get("topic", "-"), t.get("direction", "-"),
                               str(t.get("msgs", "-")), str(t.get("msgs_per_s", "-")),
                               "-" if rate is None else f"{rate / 1024:.1f}", latency, str(t.get("drops", "-")))
        return [nodes, relays]

    def refresh(self, plan: Plan) -> list[Refreshed]:
        return [Refreshed(plan.target, True, self.no_cloud.format(verb="refresh") + f" (target {plan.target})")]

    def sweep(self, plan: Plan, *, dry_run: bool) -> SweepOutcome:
        return SweepOutcome(note=f"target {plan.target} " + self.no_cloud.format(verb="sweep")
                            + "; `fogiac down` stops and removes what fogiac started")
