"""Provision and connect, the path every target ends on; and the base of targets whose
machines already exist (``local`` sandboxes, ``hosts``).

Up: certificates, (optionally) the edge's ROS master for a demo, provisioning of every host in
parallel, then one edge relay per host, supervised, joining the edge master to that host's
master over mutual TLS. Down undoes each of these and then proves it: no supervised process
alive, nothing of the target left. Everything lives in the stack's state folder.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fogiac import deployment
from fogiac.certs import load_or_create_bundle
from fogiac.errors import FogiacError, ProvisionError
from fogiac.net import middleware
from fogiac.net.relay import deploy
from fogiac.plan import guard
from fogiac.plan.document import APPLIED_FILE, plan_document
from fogiac.plan.model import HostSpec, Plan
from fogiac.provision import HostAccess, idle, provision, recorded_access, supervise, teardown
from fogiac.provision.runner import KNOWN_HOSTS
from fogiac.state import read_json, stack_dir, stack_lock, write_json_atomic
from fogiac.tables import table
from fogiac.targets.base import DownOptions, DownResult, Refreshed, SweepOutcome, UpOptions, UpResult

DEPLOYMENT_FILE = "deployment.json"
EDGE_DIR = "edge"
EDGE_MASTER = deploy.EDGE_MASTER  # the demo's edge roscore, kept by down --keep-master
STATS_STALE_S = 30.0  # a relay writes its stats every second: this much older and it no longer runs


@dataclass(frozen=True)
class FleetUp:
    report: Any  # fogiac.provision.runner.ProvisionReport
    relays: Mapping[str, str]  # host -> HOST:PORT the edge relay connects to
    edge_master: str
    deployment: Path
    notes: tuple[str, ...] = ()  # the middleware's lines for the user: files written, what to install


def edge_dir(plan: Plan) -> Path:
    return stack_dir(plan.stack) / EDGE_DIR


def ensure_edge_master(plan: Plan, uri: str, *, start: bool) -> None:
    """The robot's side must be there before anything is provisioned (the middleware says what that means)."""
    middleware.deployment(plan.middleware).prepare_edge(plan, uri, folder=edge_dir(plan), start=start)


def dialed_addresses(connect: Mapping[str, str]) -> dict[str, str]:
    """host -> the address alone, from ``connect``'s ``HOST:PORT`` (``[v6]:PORT`` too)."""
    return {host: address.rsplit(":", 1)[0].strip("[]") for host, address in connect.items()}


def provision_and_connect(plan: Plan, *, access: Mapping[str, Any], connect: Mapping[str, str], master: str,
                          started_edge_master: bool = False,
                          progress: Callable[[str, str, str], None] | None = None) -> FleetUp:
    """Provision every host, start the middleware's edge side for the hosts that came up, record the deployment.

    Every target ends here: ``local`` and ``hosts`` with their own access records, ``aws`` with
    the instances' addresses and pinned host keys. A failed host fails the run; the others stay
    up so ``fogiac down`` (or a fixed re-run) finds them.
    """
    folder = stack_dir(plan.stack)
    certs = folder / "certs"
    load_or_create_bundle(plan.stack, certs)
    report = provision(plan, hosts=access, state_dir=folder, certs_dir=certs, progress=progress,
                       dialed=dialed_addresses(connect))
    relays = {o.host: connect[o.host] for o in report.hosts if o.ok and o.host in connect}
    notes = middleware.deployment(plan.middleware).edge_up(plan, entry=master, connect=relays, certs=certs,
                                                           folder=edge_dir(plan)) if relays else []
    deployment = folder / DEPLOYMENT_FILE
    write_json_atomic(deployment, {
        "target": plan.target, "edge_master": master, "relays": relays,
        "started_edge_master": started_edge_master, "nodes": {n.name: n.host for n in plan.nodes},
    })
    if not report.ok:
        lines = [o.error or f"{o.host}: failed" for o in report.failed]
        raise ProvisionError("; ".join(lines) + " (the other hosts are up; `fogiac down` removes everything)")
    return FleetUp(report=report, relays=relays, edge_master=master, deployment=deployment, notes=tuple(notes))


def _duration(seconds: float) -> str:
    minutes = int(seconds // 60)
    return f"{minutes // 60}h{minutes % 60:02d}m" if minutes >= 60 else f"{minutes}m{int(seconds % 60):02d}s"


def edge_services(plan: Plan) -> list[str]:
    folder = stack_dir(plan.stack, create=False) / EDGE_DIR  # asking creates nothing
    return sorted(p.stem for p in folder.glob("*.pid")) if folder.exists() else []


def edge_idle_since(plan: Plan, *, now: float) -> float | None:
    """Since when no edge relay of the stack has run on this machine, from their stats files.

    A running relay rewrites its stats every second: a fresh file that says connected means an
    edge is there now (None); a stale one dates the relay's last breath. A fresh file that says
    disconnected cannot be dated, nor can a relay this machine never ran: None, unknown.
    """
    last: list[float] = []
    for route in plan.relay:
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

    def forget(self, plan: Plan, folder: Path) -> None:
        """Drop what :meth:`access` recorded, once ``down`` found nothing left."""

    def node_states(self, plan: Plan, spec: HostSpec, entry: Any) -> list[dict[str, Any]]:
        return [{"node": n} for n in spec.nodes]

    def autostop_states(self, plan: Plan, recorded: Mapping[str, Any]) -> dict[str, dict[str, Any] | None]:
        """Each host's idle watchdog's last word (idle_since, stops_at, stopped_at), read on the hosts the
        way provisioning reaches them, all at once; ``{"unreachable": why}`` for one that does not answer."""
        if plan.autostop is None:
            return {}
        ask = {spec.name: (recorded[spec.name][0], recorded[spec.name][1]) for spec in plan.hosts
               if recorded.get(spec.name) is not None}
        return idle.read_all(ask, known_hosts=stack_dir(plan.stack) / KNOWN_HOSTS, stack=plan.stack)

    def declare(self, plan: Plan) -> tuple[Mapping[str, Any], ...]:
        return ()  # nothing is created: the machines exist

    def up(self, plan: Plan, opts: UpOptions) -> UpResult:
        master = opts.edge_master or plan.edge_master
        opts.show(plan_document(plan, self.declare(plan), manifest=opts.manifest_path), None)
        question = f"Deploy {len(plan.nodes)} node(s) to {len(plan.hosts)} {plan.target} host(s)?"
        if not opts.yes and not opts.confirm(question):
            raise FogiacError("not applied: nothing was changed")
        with stack_lock(plan.stack, operation="up"):
            before = deployment.read(plan.stack)
            fresh = before is not None and not before.exists
            deployment.begin(plan, opts.manifest_path)  # before anything exists, so down always finds it
            try:
                ensure_edge_master(plan, master, start=opts.start_edge_master)
            except FogiacError:
                if before is None:
                    deployment.forget(plan.stack)
                elif fresh:
                    deployment.removed(plan.stack)
                raise
            access = self.access(plan, state_dir=stack_dir(plan.stack))
            connect = {host: self.connect_address(plan, host, a) for host, a in access.items()}
            done = provision_and_connect(plan, access=access, connect=connect, master=master,
                                         started_edge_master=opts.start_edge_master)
            for note in done.notes:
                opts.announce(note)
            # What `fogiac plan` compares with (the same document it builds), as the aws target records it.
            applied = plan_document(plan, self.declare(plan), manifest=opts.manifest_path)
            write_json_atomic(stack_dir(plan.stack) / APPLIED_FILE, applied)
            deployment.finish(plan, opts.manifest_path, plan_digest=applied["plan_digest"])
        return UpResult(outputs={"relays": dict(done.relays)}, applied=done.deployment, report=done.report,
                        relays=done.relays, edge_master=master)

    def down(self, plan: Plan, opts: DownOptions) -> DownResult:
        """Stop the edge relays, tear every host down, then prove nothing is left."""
        folder = stack_dir(plan.stack, create=False)
        record = deployment.read(plan.stack)
        if (record is None or not record.exists) and not recorded_access(folder) and not edge_services(plan):
            return DownResult(engine_errors=(), left=(), not_checked=(), existed=False)  # and nothing created
        errors: list[str] = []
        deleted = [f"edge process {name}" for name in edge_services(plan)
                   if supervise.status(edge_dir(plan), name)["running"]]
        with stack_lock(plan.stack, operation="down"):
            stop_edge(plan, keep_master=True)
            try:
                report = teardown(plan, hosts=self.access(plan, state_dir=folder), state_dir=folder)
                errors += [o.error or f"{o.host}: failed" for o in report.failed]
                deleted += [f"{o.host} process {name}" for o in report.hosts for name in o.stopped]
            except FogiacError as err:
                errors.append(str(err))
            stop_edge(plan)
            left = [f"process {name} (pid {supervise.status(edge_dir(plan), name)['pid']})"
                    for name in edge_services(plan) if supervise.status(edge_dir(plan), name)["running"]]
            left += self.leftovers(plan, folder)
            if not left and not errors:
                (folder / DEPLOYMENT_FILE).unlink(missing_ok=True)
                (folder / APPLIED_FILE).unlink(missing_ok=True)
                deployment.removed(plan.stack)
                self.forget(plan, folder)
        return DownResult(engine_errors=tuple(errors), left=tuple(left), not_checked=(), deleted=tuple(deleted))

    def host_address(self, plan: Plan, spec: HostSpec, entry: Any) -> str:
        """Where a host is reached, for ``status`` (a relay's HOST:PORT on targets without SSH)."""
        return spec.address or "-"

    def status(self, plan: Plan, *, now: float | None = None) -> dict[str, Any]:
        """Hosts (address, uptime, cost so far), nodes, edge processes, relayed topics and the cost guard."""
        head = {"stack": plan.stack, "target": plan.target}
        folder = stack_dir(plan.stack, create=False)
        record = deployment.read(plan.stack)
        record = record if record is not None and record.exists else None
        recorded = recorded_access(folder)
        if record is None and not recorded:
            return {**head, "deployed": False, "hosts": [], "relays": [], "edge": []}
        uptime = max(0.0, time.time() - record.since_epoch) if record else 0.0
        watched = self.autostop_states(plan, recorded)
        hosts = [{"host": spec.name, "machine": spec.machine,
                  "address": self.host_address(plan, spec, recorded.get(spec.name)),
                  "uptime_s": round(uptime), "cost_usd": round(spec.usd_per_hour * uptime / 3600, 4),
                  "nodes": self.node_states(plan, spec, recorded.get(spec.name)),
                  "autostop": watched.get(spec.name)} for spec in plan.hosts]
        saved = (read_json(folder / DEPLOYMENT_FILE) or {}) if folder.exists() else {}
        relays = middleware.deployment(plan.middleware).edge_links(plan, folder=edge_dir(plan),
                                                                   connect=saved.get("relays", {}))
        edge = [supervise.status(edge_dir(plan), name) for name in edge_services(plan)]
        return {**head, "deployed": True, "partial": record is None or record.partial,
                "edge_master": saved.get("edge_master", plan.edge_master), "hosts": hosts, "relays": relays,
                "edge": edge, "cost": self._guard(plan, hosts, now=time.time() if now is None else now)}

    def _guard(self, plan: Plan, hosts: list[dict[str, Any]], *, now: float) -> dict[str, Any]:
        """These machines cost nothing fogiac can price; the guard still asks whether they run with no edge.

        The hosts' watchdogs know best when the edge left (their ``idle_since``); without them, the
        edge relays' stats files on this machine.
        """
        specs = {spec.name: spec for spec in plan.hosts}
        billed = [guard.Billed(f"host {h['host']}", specs[h["host"]].usd_per_hour, None,
                               running=not (h["autostop"] or {}).get("stopped_at")) for h in hosts]
        watched = [h["autostop"] for h in hosts if h["autostop"]]
        if watched and len(watched) == len(hosts):
            idle = [w.get("idle_since") for w in watched]
            since = None if None in idle else max(idle)
        else:
            since = edge_idle_since(plan, now=now)
        return guard.guard(billed, now=now, autostop_s=plan.autostop.idle_s if plan.autostop else None,
                           edge_idle_since=since)

    def render_status(self, doc: Mapping[str, Any]) -> list[Any]:
        """Nodes with their supervision state, then relayed topics with live figures."""
        if not doc.get("deployed"):
            return [f"{doc['stack']}: not deployed"]
        out: list[Any] = []
        if doc.get("partial"):
            out.append(f"{doc['stack']}: partial: the last up did not finish; `fogiac up` completes it, "
                       "`fogiac down` removes what it started")
        nodes = table(f"{doc['stack']} ({doc['target']}), edge {doc.get('edge_master')}",
                      "host", "machine", "address", "uptime", "cost so far", "node", "state", "restarts")
        for host in doc["hosts"]:
            for node in host["nodes"]:
                state = "-" if "running" not in node else "running" if node["running"] else "stopped"
                nodes.add_row(host["host"], host["machine"], host["address"], _duration(host["uptime_s"]),
                              f"${host['cost_usd']:.2f}", node["node"], state, str(node.get("restarts", "-")))
        out.append(nodes)
        out += [f"{host['host']}: {autostop_line(host['autostop'])}" for host in doc["hosts"] if host.get("autostop")]
        running = [e for e in doc.get("edge", []) if e["running"]]
        if running:
            out.append("edge processes: " + ", ".join(f"{e['name']} (pid {e['pid']})" for e in running))
        relays = table("relayed topics (direction as in the manifest: in = robot to node)", "host", "link", "topic",
                       "dir", "msgs", "msgs/s", "KiB/s", "latency ms", "drops")
        for relay in doc["relays"]:
            rtt = f" {relay['rtt_ms']:.2f} ms" if relay.get("rtt_ms") else ""
            link = ("up" if relay.get("connected") else "down") + rtt
            for t in relay.get("topics", []) or [{}]:
                latency = "-" if t.get("latency_ms") is None else f"{t['latency_ms']:.2f}"
                rate = t.get("bytes_per_s")
                relays.add_row(relay["host"], link, t.get("topic", "-"), t.get("direction", "-"),
                               str(t.get("msgs", "-")), str(t.get("msgs_per_s", "-")),
                               "-" if rate is None else f"{rate / 1024:.1f}", latency, str(t.get("drops", "-")))
        if doc["relays"]:
            out.append(relays)
        warning = (doc.get("cost") or {}).get("warning")
        return out + ([f"warning: {warning}"] if warning else [])

    def refresh(self, plan: Plan) -> list[Refreshed]:
        return [Refreshed(plan.target, True, self.no_cloud.format(verb="refresh") + f" (target {plan.target})")]

    def sweep(self, plan: Plan, *, dry_run: bool) -> SweepOutcome:
        return SweepOutcome(note=f"target {plan.target} " + self.no_cloud.format(verb="sweep")
                            + "; `fogiac down` stops and removes what fogiac started")


def autostop_line(state: Mapping[str, Any], now: float | None = None) -> str:
    """``stopped by autostop at 12:03:10 UTC`` or ``idle 4m 10s, stops at ...`` or ``in use``."""
    now = time.time() if now is None else now

    def clock(t: float) -> str:
        return time.strftime("%H:%M:%S UTC", time.gmtime(t))

    if state.get(idle.UNREACHABLE):
        return f"idle time unknown ({idle.UNREACHABLE}: {state[idle.UNREACHABLE]})"
    if state.get("stopped_at"):
        verb = "terminated" if state.get("action") == "terminate" else "stopped"
        return f"{verb} by autostop at {clock(state['stopped_at'])} (idle since {clock(state['idle_since'])})"
    if state.get("idle_since") is None:
        return f"in use (autostop {state.get('action', 'stop')} after idle)"
    idle_s = int(now - state["idle_since"])
    return f"idle {idle_s // 60}m {idle_s % 60}s, autostop at {clock(state['stops_at'])}"
