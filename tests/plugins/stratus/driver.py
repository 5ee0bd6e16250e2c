"""Stratus's answers to the lifecycle: its platform runs each host's processes; fogiac reaches none of them.

``create`` hands the platform one pod per planned host (its ROS master, its nodes, the relay's cloud
end with a certificate of its own, signed by the stack's CA) and ``reach`` answers only the link the
robot's edge dials for each; the lifecycle then starts the edge's end. ``down`` has the platform stop
its pods and proves no process of theirs is left.
"""

from __future__ import annotations

import os
import shutil
import sys
import xmlrpc.client
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from fogiac.certs import issue, load_or_create_bundle, write_private
from fogiac.errors import FogiacError, ProvisionError
from fogiac.lifecycle.driver import (
    Check,
    Created,
    Destroyed,
    DownOptions,
    Feature,
    Machine,
    Prepared,
    Reach,
    Refreshed,
    SweepOutcome,
)
from fogiac.lifecycle.events import OnEvent
from fogiac.manifest.schema import Manifest
from fogiac.net.relay.tls import relay_name
from fogiac.plan.model import NodeSpec, Plan
from fogiac.plan.placement import Placement, Tags, host_per_node
from fogiac.procs import free_port, poll
from fogiac.provision import workload
from fogiac.resources import package_dir
from fogiac.state import StackState
from tests.plugins.stratus.platform import Container, Platform, members

RECORD = "stratus.json"  # what the stratus platform holds for the stack
PODS = "stratus"  # the pods' folders, under the stack's


class StratusTarget:
    name = "stratus"
    summary = "stratus pods (a platform defined in the tests: it runs the nodes itself, no SSH)"
    features = frozenset({Feature.CREATES_MACHINES})  # and no Feature.PROVISIONS: the platform runs the nodes

    def _platform(self, plan: Plan) -> Platform:
        return Platform(StackState(plan.stack).target_file(RECORD))

    def _pod(self, plan: Plan, host: str) -> str:
        return f"{plan.stack}-{host}"

    def place(self, manifest: Manifest, *, stack: str, tags: Tags) -> Placement:
        hosts, node_hosts = host_per_node(manifest, stack=stack, tags=tags, address="127.0.0.1")
        return Placement(hosts=hosts, node_hosts=node_hosts, mode="relay", connect_via="loopback")

    def declare(self, plan: Plan) -> tuple[Mapping[str, Any], ...]:
        return tuple({"stack": "pods", "type": "stratus:run:Pod", "name": self._pod(plan, h.name), "action": "create",
                      "inputs": {"nodes": list(h.nodes)}} for h in plan.hosts)

    def ready(self, plan: Plan, *, verb: str) -> None:
        if verb == "up" and shutil.which("roscore") is None:
            raise FogiacError("stratus pods run ROS 1's roscore: not on PATH (install ros-core)")

    def prepare(self, plan: Plan, *, ssh_from: str | None) -> Prepared:
        for node in plan.nodes:
            if node.workload is None and not node.command:
                raise FogiacError(f"stratus runs workload and command nodes; node {node.name} is neither")
        return Prepared(plan=plan, question=f"Run {len(plan.hosts)} stratus pod(s)?")

    def create(self, plan: Plan, prepared: Prepared, *, announce: Callable[[str], None],
               on_event: OnEvent | None) -> Created:
        """One pod per host, started by the platform; a pod that still runs is kept (a second up changes nothing)."""
        state = StackState(plan.stack)
        bundle = load_or_create_bundle(plan.stack, state.certs)
        platform = self._platform(plan)
        made = []
        for host in plan.hosts:
            name = self._pod(plan, host.name)
            if not platform.running(name):
                platform.stop(name)  # what is left of a pod that broke
                folder = state.target_file(PODS) / host.name
                folder.mkdir(parents=True, exist_ok=True, mode=0o700)
                _certificate(folder / "certs", bundle.ca, relay_name(plan.stack, host.name))
                master, relay = free_port(), free_port()
                platform.start(name, folder, _containers(plan, host.name, folder, master=master, relay=relay),
                               ready=lambda c, m=master: _wait_master(c, m),
                               facts={"host": host.name, "master_port": master, "relay_port": relay})
            made.append(Machine(host.name, platform.pods()[name]["id"], host.machine, "127.0.0.1"))
        return Created(plan=plan, outputs={"pods": {m.host: m.id for m in made}}, machines=tuple(made))

    def reach(self, plan: Plan, created: Created, *, announce: Callable[[str], None]) -> Reach:
        """No runner for any host (fogiac opens none); the relay's cloud end each pod serves, for the edge."""
        pods = self._platform(plan).pods()
        return Reach(access={}, connect={h.name: f"127.0.0.1:{pods[self._pod(plan, h.name)]['relay_port']}"
                                         for h in plan.hosts if self._pod(plan, h.name) in pods})

    def access_from(self, description: Mapping[str, Any]) -> Any:
        raise ProvisionError("stratus runs its nodes itself: fogiac records no host access for it")

    def recorded(self, plan: Plan) -> bool:
        return bool(self._platform(plan).pods())

    def destroy(self, plan: Plan, opts: DownOptions) -> Destroyed:
        platform = self._platform(plan)
        deleted, left = [], []
        for name, pod in sorted(platform.pods().items()):
            still = platform.stop(name)
            if still:
                left += [f"pod {pod['id']} process {pid}" for pid in still]
            else:
                deleted.append(f"pod {pod['id']}")
        return Destroyed(deleted=tuple(deleted), left=tuple(left))

    def forget(self, plan: Plan, *, keep_network: bool) -> None:
        state = StackState(plan.stack)
        shutil.rmtree(state.target_file(PODS), ignore_errors=True)
        state.target_file(RECORD).unlink(missing_ok=True)

    def describe(self, plan: Plan, *, now: float) -> dict[str, Any]:
        platform = self._platform(plan)
        return {"hosts": [{"host": pod["host"], "pod": pod["id"], "running": platform.running(name),
                           "processes": len(members(set(pod["sessions"].values())))}
                          for name, pod in sorted(platform.pods().items())]}

    def render_status(self, doc: Mapping[str, Any]) -> list[Any]:
        return [f"{h['host']}: {h['pod']} {'running' if h['running'] else 'stopped'}" for h in doc["hosts"]] or \
            [f"{doc['stack']}: no stratus pods"]

    def doctor(self, plan: Plan, *, ssh_from: str | None = None) -> list[Check]:
        found = shutil.which("roscore")
        return [Check("roscore", found is not None, found or "not on PATH")]

    def refresh(self, plan: Plan) -> list[Refreshed]:
        return [Refreshed("stratus", True, f"{len(self._platform(plan).pods())} pod(s)")]

    def sweep(self, plan: Plan, *, dry_run: bool) -> SweepOutcome:
        return SweepOutcome(note="stratus keeps nothing outside the stack's record")


STRATUS = StratusTarget()


def _certificate(folder: Path, ca: Any, name: str) -> None:
    """The relay's cloud end shows a certificate for the pod's own name, signed by the stack's CA (a
    platform hands it in as a secret); the key is written 0600."""
    folder.mkdir(parents=True, exist_ok=True, mode=0o700)
    pair = issue(ca, name, server=True, dns_names=(name,))
    (folder / "ca.pem").write_bytes(ca.cert_pem)
    (folder / "server.pem").write_bytes(pair.cert_pem)
    write_private(folder / "server.key", pair.key_pem)


def _node_argv(node: NodeSpec) -> tuple[str, ...]:
    if node.workload is not None:
        return (sys.executable, "-m", workload.package(node.workload), "node")
    return tuple(node.command)


def _containers(plan: Plan, host: str, folder: Path, *, master: int, relay: int) -> list[Container]:
    """The pod: the host's ROS master, its nodes, then the relay's cloud end (the platform's part of the link)."""
    uri = f"http://127.0.0.1:{master}"
    code = str(package_dir("fogiac").parent)  # this checkout's fogiac and workloads
    env = {k: v for k, v in os.environ.items() if k != "ROS_HOSTNAME"}
    env |= {"ROS_MASTER_URI": uri, "ROS_IP": "127.0.0.1", "ROS_HOME": str(folder / "ros"),
            "PYTHONPATH": os.pathsep.join(p for p in (code, env.get("PYTHONPATH", "")) if p)}
    route = next(r for r in plan.routes if r.host == host)
    spec = plan.host(host)
    nodes = [Container(f"node-{n}", _node_argv(plan.node(n)), {**env, **dict(plan.node(n).env)}) for n in spec.nodes]
    cloud_end = (sys.executable, "-m", "fogiac", "relay", "cloud", "--listen", f"127.0.0.1:{relay}", "--master", uri,
                 "--certs", str(folder / "certs"), "--ros-host", "127.0.0.1",
                 "--stats-file", str(folder / "relay-cloud.stats.json"), *route.policy_argv())
    return [Container("ros-master", ("roscore", "-p", str(master)), env), *nodes,
            Container("relay-cloud", cloud_end, env)]


def _wait_master(container: Container, port: int) -> None:
    """After the master starts, the rest wait for it to answer (the nodes register there)."""
    if container.name != "ros-master":
        return

    def answers() -> bool | None:
        try:
            xmlrpc.client.ServerProxy(f"http://127.0.0.1:{port}").getPid("/stratus")
        except (OSError, xmlrpc.client.Error):
            return None
        return True

    if poll(answers, timeout=30, interval=0.2, backoff=1.0) is None:
        raise FogiacError(f"the stratus pod's ROS master did not answer on port {port}")
