"""The ``hosts`` target's lifecycle (its placement is :mod:`.placement`)."""

from __future__ import annotations

import shutil
import socket
from collections.abc import Mapping
from pathlib import Path

from fogiac.errors import ProvisionError
from fogiac.manifest.schema import Manifest
from fogiac.plan.model import Plan
from fogiac.plan.placement import Placement, Tags
from fogiac.provision import SshAccess
from fogiac.targets.base import Check
from fogiac.targets.existing import ExistingMachines
from fogiac.targets.hosts import placement

CONNECT_TIMEOUT_S = 5.0  # doctor's TCP check of each host's SSH port


class HostsTarget(ExistingMachines):
    name = "hosts"
    summary = "existing machines reached over SSH (lab servers)"

    def place(self, manifest: Manifest, *, stack: str, tags: Tags) -> Placement:
        return placement.place(manifest, stack=stack, tags=tags)

    access_kind = SshAccess

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
