"""The ``hosts`` target: machines that already exist, reached over SSH (a lab GPU server is fog too).

Nodes are placed on the manifest's ``cloud.hosts`` (a node's ``host:``, else round robin);
the edge relay dials each host's address. Host keys are trusted on first use and pinned.
A lab machine is shared: each stack's ROS master and relay listen on ports of its own
(:func:`stack_ports`), beside the lab's own roscore on 11311 and any other stack.
"""

from __future__ import annotations

import hashlib
import shutil
import socket
from collections.abc import Mapping
from pathlib import Path

from fogiac.errors import PlanError, ProvisionError
from fogiac.manifest.schema import Manifest
from fogiac.orchestrate import ExistingMachines
from fogiac.plan.model import RELAY_PORT, HostSpec, Plan
from fogiac.plan.placement import Placement, Tags, autostop_for, steps_for
from fogiac.provision import SshAccess
from fogiac.targets.base import Check

CONNECT_TIMEOUT_S = 5.0  # doctor's TCP check of each host's SSH port
# Stacks' port pairs (master, master + 1 for the relay) lie in 20000-29999: below Linux's ephemeral
# range (32768-60999), where nodes listen, and clear of ROS's 11311 and the relay's 11411.
_PORTS_FROM, _PORT_PAIRS = 20000, 5000


def stack_ports(stack: str) -> tuple[int, int]:
    """(ROS master port, relay port) of ``stack`` on every host: the same on every run, from its name.

    Two stacks meet on one pair once in 5000; the second master then cannot bind and its health
    step names the port, rather than two stacks silently sharing a graph.
    """
    pair = int.from_bytes(hashlib.sha256(stack.encode()).digest()[:4], "big") % _PORT_PAIRS
    master = _PORTS_FROM + 2 * pair
    return master, master + 1


class HostsTarget(ExistingMachines):
    name = "hosts"
    summary = "existing machines reached over SSH (lab servers)"

    def place(self, manifest: Manifest, *, stack: str, tags: Tags) -> Placement:
        machines = manifest.cloud.hosts
        if not machines:
            raise PlanError("cloud.hosts: the hosts target needs at least one machine")
        node_hosts = {node.name: node.host or machines[i % len(machines)].name
                      for i, node in enumerate(manifest.nodes)}
        master_port, relay_port = stack_ports(stack)
        hosts = []
        for machine in machines:
            placed = [n for n in manifest.nodes if node_hosts[n.name] == machine.name]
            if not placed:
                continue
            for node in placed:
                if node.gpu and machine.gpus == 0:
                    raise PlanError(f"nodes.{node.name}: needs a GPU but host {machine.name!r} has gpus: 0")
            hosts.append(HostSpec(
                name=machine.name, machine="lab", vcpus=0, gpus=machine.gpus, memory_gib=0.0, usd_per_hour=0.0,
                spot=False, disk_gb=0, nodes=tuple(n.name for n in placed), steps=steps_for(placed),
                tags=tags + (("fogiac:node", ",".join(n.name for n in placed)),),
                address=machine.address, user=machine.user, port=machine.port, key=str(machine.key),
                runtime=manifest.cloud.runtime, master_port=master_port, relay_port=relay_port,
            ))
        return Placement(hosts=tuple(hosts), node_hosts=node_hosts, mode="relay", connect_via="address",
                         autostop=autostop_for(manifest, power="services", default_minutes=None))

    def access(self, plan: Plan, *, state_dir: Path, python: str = "python3",
               connect_timeout: float = 60.0) -> Mapping[str, SshAccess]:
        out: dict[str, SshAccess] = {}
        for spec in plan.hosts:
            if not (spec.address and spec.user and spec.key):
                raise ProvisionError(f"host {spec.name}: the plan lacks its address, user or key")
            out[spec.name] = SshAccess(address=spec.address, user=spec.user, port=spec.port or 22, key=Path(spec.key),
                                       python=python, connect_timeout=connect_timeout, master_port=spec.master_port,
                                       relay_port=spec.relay_port or RELAY_PORT)
        return out

    def doctor(self, plan: Plan, *, ssh_from: str | None = None) -> list[Check]:
        """What ``up`` needs before it connects: roscore for the edge, each key, each SSH port answering."""
        checks = [_roscore_check()]
        for spec in plan.hosts:
            key = Path(spec.key or "")
            found = key.is_file()
            checks.append(Check(f"{spec.name} key", found, str(key) if found else f"{key}: no such file"))
            try:
                with socket.create_connection((spec.address or "", spec.port or 22), timeout=CONNECT_TIMEOUT_S):
                    checks.append(Check(f"{spec.name} ssh", True, f"{spec.address}:{spec.port or 22} answers"))
            except OSError as err:
                checks.append(Check(f"{spec.name} ssh", False, f"{spec.address}:{spec.port or 22}: {err}"))
        return checks


def _roscore_check() -> Check:
    found = shutil.which("roscore")
    return Check("edge roscore", found is not None,
                 found or "not on PATH (needed only with --start-edge-master; install ros-core)")


HOSTS = HostsTarget()
