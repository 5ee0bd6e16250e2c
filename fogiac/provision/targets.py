"""How to reach each planned host, per target: a registry from target name to access records.

``hosts`` reads address, user, port and key from the plan (trust on first use); ``local``
makes sandboxes under the state folder. ``aws`` hosts come from the stack outputs, with host
keys pinned from the instances' console output, so the caller builds those ``SshAccess``
records itself.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Mapping

from fogiac.errors import ProvisionError
from fogiac.plan import Plan
from fogiac.provision.host import HostAccess, SshAccess
from fogiac.provision.local import local_access


def hosts_access(plan: Plan, *, state_dir: Path, python: str = "python3",
                 connect_timeout: float = 60.0) -> Mapping[str, HostAccess]:
    out: dict[str, HostAccess] = {}
    for spec in plan.hosts:
        if not (spec.address and spec.user and spec.key):
            raise ProvisionError(f"host {spec.name}: the plan lacks its address, user or key")
        out[spec.name] = SshAccess(address=spec.address, user=spec.user, port=spec.port or 22, key=Path(spec.key),
                                   python=python, connect_timeout=connect_timeout)
    return out


def aws_access(plan: Plan, *, state_dir: Path) -> Mapping[str, HostAccess]:
    raise ProvisionError("aws hosts are reached from the stack's outputs: run `fogiac up`, "
                         "which pins each instance's host key from its console output")


ACCESS: dict[str, Callable[..., Mapping[str, HostAccess]]] = {
    "hosts": hosts_access,
    "local": lambda plan, *, state_dir, **_: local_access(plan, state_dir=state_dir),
    "aws": aws_access,
}


def access_for(plan: Plan, *, state_dir: Path, **options: object) -> Mapping[str, HostAccess]:
    try:
        make = ACCESS[plan.target]
    except KeyError:
        raise ProvisionError(f"unknown target {plan.target!r}; valid: {', '.join(ACCESS)}") from None
    return make(plan, state_dir=state_dir, **options)
