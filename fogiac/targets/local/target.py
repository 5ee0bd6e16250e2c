"""The ``local`` target's lifecycle (its placement is :mod:`.placement`)."""

from __future__ import annotations

import importlib.util
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from fogiac.manifest.schema import Manifest
from fogiac.plan.model import HostSpec, Plan
from fogiac.plan.placement import Placement, Tags
from fogiac.provision import HostPorts, LocalAccess, supervise
from fogiac.provision.local import PORTS_FILE, local_access, local_ports, sandbox_root
from fogiac.state import StackState
from fogiac.targets.base import Check
from fogiac.targets.existing import ExistingMachines
from fogiac.targets.local import placement


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
        return [{"node": node, **supervise.status(run_dir, f"node-{node}")} for node in spec.nodes]

    def doctor(self, plan: Plan, *, ssh_from: str | None = None) -> list[Check]:
        """What the sandboxes need on this machine: ROS 1's roscore and rospy."""
        roscore = shutil.which("roscore")
        rospy = importlib.util.find_spec("rospy")
        return [
            Check("roscore", roscore is not None, roscore or "not on PATH (install ros-core)"),
            Check("rospy", rospy is not None,
                  (rospy.origin or "found") if rospy else "not importable (install python3-rospy)"),
        ]


LOCAL = LocalTarget()
