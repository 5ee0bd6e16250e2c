"""Provisioning: make hosts run ROS, the nodes and the relay, in parallel and idempotently.

The lead's entry points::

    from fogiac.provision import provision, teardown, SshAccess
    report = provision(plan, hosts=access, state_dir=d, certs_dir=d / "certs")
    print(report.summary())          # "no changes" on a re-run

``access`` maps each planned host to how it is reached (a :class:`HostAccess`); each target
makes its own (``fogiac.targets.<name>``). On ``aws`` build ``SshAccess(address=...,
user="ubuntu", key=d / "ssh_key", fingerprints=(...))`` per host from the stack outputs and the
instances' console output; ``local`` takes :func:`fogiac.provision.local.local_access`.
"""

from __future__ import annotations

from fogiac.provision.host import Host, HostAccess, Result
from fogiac.provision.local import LocalAccess
from fogiac.provision.runner import (
    HostOutcome,
    ProvisionReport,
    StepOutcome,
    access_from_dict,
    provision,
    recorded_access,
    stop_all,
    teardown,
)
from fogiac.provision.ssh import SshAccess

__all__ = [
    "Host", "HostAccess", "HostOutcome", "LocalAccess", "ProvisionReport", "Result", "SshAccess", "StepOutcome",
    "access_from_dict", "provision", "recorded_access", "stop_all", "teardown",
]
