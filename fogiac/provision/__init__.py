"""Provisioning: make hosts run ROS, the nodes and the relay, in parallel and idempotently.

The lead's entry points::

    from fogiac.provision import provision, teardown, access_for, SshAccess
    report = provision(plan, hosts=access_for(plan, state_dir=d), state_dir=d, certs_dir=d / "certs")
    print(report.summary())          # "no changes" on a re-run

On ``aws`` build ``SshAccess(address=..., user="ubuntu", key=d / "ssh_key", fingerprints=(...))``
per host from the stack outputs and the instances' console output.
"""

from __future__ import annotations

from fogiac.provision.host import Host, HostAccess, LocalAccess, Result, SshAccess
from fogiac.provision.runner import (
    HostOutcome,
    ProvisionReport,
    StepOutcome,
    provision,
    recorded_access,
    stop_all,
    teardown,
)
from fogiac.provision.targets import access_for

__all__ = [
    "Host", "HostAccess", "HostOutcome", "LocalAccess", "ProvisionReport", "Result", "SshAccess", "StepOutcome",
    "access_for", "provision", "recorded_access", "stop_all", "teardown",
]
