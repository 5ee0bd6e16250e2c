"""The ``hosts`` target: machines that already exist, reached over SSH (a lab GPU server is fog too).

Nodes are placed on the manifest's ``cloud.hosts`` (a node's ``host:``, else round robin);
the edge relay dials each host's address. Host keys are trusted on first use and pinned.
"""

from __future__ import annotations

import shutil
import socket
from collections.abc import Mapping
from pathlib import Path

from fogiac.errors import PlanError, ProvisionError
from fogiac.manifest.schema import Manifest
from fogiac.orchestrate import ExistingMachines
from fogiac.plan.model import HostSpec, Plan
from fogiac.plan.placement import Placement, Tags, autostop_for, steps_for
from fogiac.provision import SshAccess
from fogiac.targets.base import Check

CONNECT_TIMEOUT_S = 5.0  # doctor's TCP check of each host's SSH port


class HostsTarget(ExistingMachines):
    name = "hosts"
    summary = "existing machines reached over SSH (lab servers)"

    def place(self, manifest: Manifest, *, stack: str, tags: Tags) -> Placement:
        machines = manifest.cloud.hosts
        if not machines:
            raise PlanError("cloud.hosts: the hosts target needs at least one machine")
        node_hosts = {node.name: node.host or machines[i % len(machines)].name
                      for i, node in enumerate(manifest.nodes)}
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
                runtime=manifest.cloud.runtime,
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
                                       python=python, connect_timeout=connect_timeout)
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
