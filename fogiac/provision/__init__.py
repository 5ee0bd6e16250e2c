"""Provisioning: make hosts run ROS, the nodes and the relay, in parallel and idempotently.

The lead's entry points::

    from fogiac.provision import provision, teardown, SshAccess
    report = provision(plan, hosts=access, state_dir=d, certs_dir=d / "certs")
    print(report.summary())          # "no changes" on a re-run

``access`` maps each planned host to how it is reached (a :class:`HostAccess`); each target
makes its own (``fogiac.targets.<name>``). On ``aws`` build ``SshAccess(address=...,
user="ubuntu", key=d / "ssh_key", fingerprints=(...))`` per host from the stack outputs and the
instances' console output; ``local`` takes :func:`fogiac.provision.local.local_access`, with
its own ports (``ports=local_ports(...)``; unset, each host's come from the plan).
"""

from __future__ import annotations

from fogiac.provision.host import Host, HostAccess, HostPorts, Result, planned_ports
from fogiac.provision.local import LocalAccess
from fogiac.provision.runner import (
    HostOutcome,
    ProvisionReport,
    StepOutcome,
    provision,
    recorded_access,
    recorded_hosts,
    stop_all,
    teardown,
)
from fogiac.provision.ssh import SshAccess

__all__ = [
    "Host", "HostAccess", "HostOutcome", "HostPorts", "LocalAccess", "ProvisionReport", "Result", "SshAccess",
    "StepOutcome", "planned_ports", "provision", "recorded_access", "recorded_hosts", "stop_all", "teardown",
]
