"""The driver base of targets whose machines exist already (``local`` sandboxes, ``hosts``).

Nothing to create, everything to provision: the lifecycle provisions every host and connects
the edge; ``down`` stops what fogiac runs there and proves it. A subclass says how to reach
each host (:meth:`access`, and :attr:`access_kind`, the access class whose recorded
descriptions it reads back), what its services listen on where the plan does not say
(:meth:`ports`), which address the edge dials (:meth:`connect_address`), what of its own could
be left (:meth:`leftovers`) and how to read a host's node states (:meth:`node_states`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from fogiac import deployment
from fogiac.lifecycle.driver import (
    Created,
    Destroyed,
    DownOptions,
    Feature,
    Prepared,
    Reach,
    Refreshed,
    SweepOutcome,
)
from fogiac.lifecycle.edge import edge_idle_since
from fogiac.lifecycle.events import OnEvent
from fogiac.lifecycle.report import autostop_line, duration
from fogiac.plan import guard
from fogiac.plan.model import HostSpec, Plan
from fogiac.provision import HostAccess, HostPorts, idle, planned_ports, recorded_access
from fogiac.state import StackState
from fogiac.tables import printable, table, usd
from fogiac.termtext import clean


class ExistingMachines:
    """Machines that exist: ``create`` makes nothing, ``destroy`` only proves what fogiac started is gone."""

    name = ""
    summary = ""
    features: frozenset[Feature] = frozenset({Feature.PROVISIONS})
    no_cloud = "has no cloud account: nothing to {verb}"
    access_kind: Any = None  # the HostAccess class this target makes: its ``from_description`` reads the record

    def access(self, plan: Plan, *, state_dir: Path) -> Mapping[str, HostAccess]:
        raise NotImplementedError

    def ports(self, plan: Plan, *, state_dir: Path) -> Mapping[str, HostPorts]:
        return planned_ports(plan)

    def connect_address(self, plan: Plan, host: str, access: HostAccess, ports: HostPorts) -> str:
        return f"{access.ros_address}:{ports.relay_port}"

    def access_from(self, description: Mapping[str, Any]) -> HostAccess:
        found: HostAccess = self.access_kind.from_description(description)
        return found

    def leftovers(self, plan: Plan, folder: Path) -> list[str]:
        return []

    def node_states(self, plan: Plan, spec: HostSpec, entry: Any) -> list[dict[str, Any]]:
        return [{"node": n} for n in spec.nodes]

    def host_address(self, plan: Plan, spec: HostSpec, entry: Any) -> str:
        """Where a host is reached, for ``status`` (a relay's HOST:PORT on targets without SSH)."""
        return spec.address or "-"

    # -- the lifecycle's questions ---------------------------------------------------------------------

    def declare(self, plan: Plan) -> tuple[Mapping[str, Any], ...]:
        return ()  # nothing is created: the machines exist

    def ready(self, plan: Plan, *, verb: str) -> None:
        return None  # nothing to check before the lock: the hosts are reached while provisioning

    def prepare(self, plan: Plan, *, ssh_from: str | None) -> Prepared:
        return Prepared(plan=plan, question=f"Deploy {len(plan.nodes)} node(s) to {len(plan.hosts)} "
                                            f"{plan.target} host(s)?")

    def create(self, plan: Plan, prepared: Prepared, *, announce: Callable[[str], None],
               on_event: OnEvent | None) -> Created:
        return Created(plan=plan)

    def reach(self, plan: Plan, created: Created, *, announce: Callable[[str], None]) -> Reach:
        folder = StackState(plan.stack).ensure()
        access, ports = self.access(plan, state_dir=folder), self.ports(plan, state_dir=folder)
        return Reach(access=access, ports=ports,
                     connect={host: self.connect_address(plan, host, a, ports[host]) for host, a in access.items()})

    def recorded(self, plan: Plan) -> bool:
        return False  # what these targets record is provisioning's access record, which the lifecycle reads

    def destroy(self, plan: Plan, opts: DownOptions) -> Destroyed:
        return Destroyed(left=tuple(self.leftovers(plan, StackState(plan.stack).folder)))

    def forget(self, plan: Plan, *, keep_network: bool) -> None:
        """Drop what :meth:`access` recorded, once ``down`` found nothing left."""

    def autostop_states(self, plan: Plan, recorded: Mapping[str, Any]) -> dict[str, dict[str, Any] | None]:
        """Each host's idle watchdog's last word (idle_since, stops_at, stopped_at), read on the hosts the
        way provisioning reaches them, all at once; ``{"unreachable": why}`` for one that does not answer."""
        if plan.autostop is None:
            return {}
        ask = {spec.name: (recorded[spec.name][0], recorded[spec.name][1]) for spec in plan.hosts
               if recorded.get(spec.name) is not None}
        return idle.read_all(ask, known_hosts=StackState(plan.stack).known_hosts, stack=plan.stack)

    def describe(self, plan: Plan, *, now: float) -> dict[str, Any]:
        """Hosts (address, uptime, cost so far, nodes, autostop) and the cost guard."""
        record = deployment.read(plan.stack)
        record = record if record is not None and record.exists else None
        recorded = recorded_access(StackState(plan.stack).folder, self.access_from)
        uptime = max(0.0, time.time() - record.since_epoch) if record else 0.0
        watched = self.autostop_states(plan, recorded)
        hosts = [{"host": spec.name, "machine": spec.machine,
                  "address": self.host_address(plan, spec, recorded.get(spec.name)),
                  "uptime_s": round(uptime), "cost_usd": (round(spec.usd_per_hour * uptime / 3600, 4)
                               if spec.usd_per_hour is not None else None),
                  "nodes": self.node_states(plan, spec, recorded.get(spec.name)),
                  "autostop": watched.get(spec.name)} for spec in plan.hosts]
        return {"hosts": hosts, "cost": self._guard(plan, hosts, now=now)}

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
            idle_since = [w.get("idle_since") for w in watched]
            since = None if None in idle_since else max(idle_since)
        else:
            since = edge_idle_since(plan, now=now)
        return guard.guard(billed, now=now, autostop_s=plan.autostop.idle_s if plan.autostop else None,
                           edge_idle_since=since)

    def render_status(self, doc: Mapping[str, Any]) -> list[Any]:
        """Nodes with their supervision state (the lifecycle adds the edge and the relayed topics)."""
        out: list[Any] = []
        if doc.get("partial"):
            out.append(f"{doc['stack']}: partial: the last up did not finish; `fogiac up` completes it, "
                       "`fogiac down` removes what it started")
        nodes = table(printable(f"{doc['stack']} ({doc['target']}), edge {doc.get('edge_master')}"),
                      "host", "machine", "address", "uptime", "cost so far", "node", "state", "restarts")
        for host in doc["hosts"]:
            for node in host["nodes"]:
                state = "-" if "running" not in node else "crash-looping" if node.get("crash_looping") else \
                    "running" if node["running"] else "stopped"
                nodes.add_row(*map(printable, (host["host"], host["machine"], host["address"],
                                               duration(host["uptime_s"]), usd(host["cost_usd"]) or "unknown",
                                               node["node"], state, node.get("restarts", "-"))))
        out.append(nodes)
        out += [printable(f"{host['host']}: node {node['node']} is crash-looping; its last line: "
                          f"{clean(node.get('last_line', ''))}") for host in doc["hosts"] for node in host["nodes"]
                if node.get("crash_looping")]
        out += [printable(f"{host['host']}: {autostop_line(host['autostop'])}")
                for host in doc["hosts"] if host.get("autostop")]
        warning = (doc.get("cost") or {}).get("warning")
        return out + ([f"warning: {warning}"] if warning else [])

    def refresh(self, plan: Plan) -> list[Refreshed]:
        return [Refreshed(plan.target, True, self.no_cloud.format(verb="refresh") + f" (target {plan.target})")]

    def sweep(self, plan: Plan, *, dry_run: bool) -> SweepOutcome:
        return SweepOutcome(note=f"target {plan.target} " + self.no_cloud.format(verb="sweep")
                            + "; `fogiac down` stops and removes what fogiac started")
