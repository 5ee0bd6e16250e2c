"""The ``local`` target's lifecycle (its placement is :mod:`.placement`)."""

from __future__ import annotations

import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from fogiac.errors import FogiacError
from fogiac.hostmodel import node_instances
from fogiac.manifest.schema import Manifest
from fogiac.plan.model import HostSpec, Plan
from fogiac.plan.placement import Placement, Tags
from fogiac.provision import HostPorts, LocalAccess, supervise
from fogiac.provision.local import PORTS_FILE, local_access, local_ports, sandbox_root
from fogiac.state import StackState
from fogiac.targets.base import Check
from fogiac.targets.existing import ExistingMachines
from fogiac.targets.local import needs, placement


class LocalTarget(ExistingMachines):
    name = "local"
    summary = "sandboxes on this machine, one ROS master each (demos, CI)"

    def place(self, manifest: Manifest, *, stack: str, tags: Tags) -> Placement:
        return placement.place(manifest, stack=stack, tags=tags)

    access_kind = LocalAccess

    def access(self, plan: Plan, *, state_dir: Path) -> Mapping[str, LocalAccess]:
        return local_access(plan, state_dir=state_dir)

    def ports(self, plan: Plan, *, state_dir: Path) -> Mapping[str, HostPorts]:
        return local_ports(plan, state_dir=state_dir)  # a sandbox's own: they share this machine

    def leftovers(self, plan: Plan, folder: Path) -> list[str]:
        return [f"sandbox {p}" for p in sorted(sandbox_root(folder).glob("*")) if p.is_dir()]

    def host_address(self, plan: Plan, spec: HostSpec, entry: Any) -> str:
        return entry[0].location if entry is not None else "-"

    def forget(self, plan: Plan, *, keep_network: bool) -> None:
        root = sandbox_root(StackState(plan.stack).folder)
        (root / PORTS_FILE).unlink(missing_ok=True)
        if root.is_dir() and not any(root.iterdir()):
            root.rmdir()

    def node_states(self, plan: Plan, spec: HostSpec, entry: Any) -> list[dict[str, Any]]:
        if entry is None:
            return super().node_states(plan, spec, entry)
        run_dir = Path(entry[1] or entry[0].sandbox) / "run"
        return [{"node": each, **supervise.status(run_dir, f"node-{each}")} for node in spec.nodes
                for each in node_instances(plan, plan.node(node))]  # a per-robot node: each instance (slam@arm1)

    def ready(self, plan: Plan, *, verb: str) -> None:
        """Before ``up`` starts anything: the workload nodes' requirements installed for this interpreter
        (the sandboxes run it), else one line naming them and the command that installs them."""
        if verb != "up":
            return
        failed = [check for check in needs.workload_problems(plan, import_nodes=False) if not check.ok]
        if failed:
            raise FogiacError("; ".join(f"{check.what}: {check.detail}" for check in failed)
                              + " (`fogiac doctor --target local` checks everything local needs)")

    def doctor(self, plan: Plan, *, ssh_from: str | None = None) -> list[Check]:
        """What the sandboxes need on this machine: ROS 1's roscore and rospy, and what each workload node
        imports (its requirements installed for the interpreter the sandboxes run, its node module)."""
        roscore = shutil.which("roscore")
        return [
            Check("roscore", roscore is not None, roscore or "not on PATH (install ros-core)"),
            needs.rospy_check(),
            *needs.workload_problems(plan, import_nodes=True),
        ]


LOCAL = LocalTarget()
