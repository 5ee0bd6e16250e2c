"""One error hierarchy for everything a user can cause or fix.

The CLI catches :class:`FogiacError` once, prints ``str(err)`` on one line (or one line per
problem for a :class:`ManifestError`) and exits 1. Anything else escaping is a bug.

    FogiacError
    ├── ManifestError          the manifest is unreadable or invalid (carries every problem)
    ├── PlanError              a saved plan is stale, corrupt or for another manifest
    ├── StateError             the state directory is unusable
    │   └── LockHeld           another fogiac holds the stack's lock
    ├── CloudError             a cloud API said no
    │   ├── CredentialsError   no usable AWS credentials
    │   ├── PreflightError     something would fail before any money is spent
    │   └── EngineError        the Pulumi engine is missing or failed
    ├── ProvisionError         a host could not be provisioned
    │   └── HostKeyError       a host presented a key other than the recorded one
    ├── RelayError             the relay could not start or lost its peer for good
    ├── ZenohError             a Zenoh router could not open (bad config, certificate, port)
    ├── VpnError               OpenVPN could not be set up
    ├── CertError              a certificate folder or request is unusable
    ├── WorkloadError          a workload's input is unusable
    └── MissingExtra           an optional dependency (fogiac[aws], [ssh], [ros2], [workloads]) is not installed
"""

from __future__ import annotations

from collections.abc import Sequence


class FogiacError(Exception):
    """Base of every error a user can act on."""


class ManifestError(FogiacError):
    """The manifest failed to load; ``problems`` holds one line per problem."""

    def __init__(self, problems: Sequence[str]) -> None:
        self.problems = list(problems)
        super().__init__("\n".join(self.problems))


class PlanError(FogiacError):
    pass


class StateError(FogiacError):
    pass


class LockHeld(StateError):
    pass


class CloudError(FogiacError):
    pass


class CredentialsError(CloudError):
    pass


class PreflightError(CloudError):
    pass


class EngineError(CloudError):
    pass


class ProvisionError(FogiacError):
    pass


class HostKeyError(ProvisionError):
    pass


class RelayError(FogiacError):
    pass


class ZenohError(FogiacError):
    pass


class VpnError(FogiacError):
    pass


class CertError(FogiacError):
    pass


class WorkloadError(FogiacError):
    pass


class MissingExtra(FogiacError):
    """An optional dependency is not installed; the message names the extra to install."""
