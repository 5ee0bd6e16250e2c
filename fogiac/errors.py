"""One error hierarchy for everything a user can cause or fix, in neutral terms.

The CLI catches :class:`FogiacError` once, prints ``str(err)`` on one line (or one line per
problem for a :class:`ManifestError`) and exits 1. Anything else escaping is a bug.

    FogiacError
    ├── ManifestError          the manifest is unreadable or invalid (carries every problem)
    ├── PlanError              a saved plan is stale, corrupt or for another manifest
    ├── StateError             the state directory is unusable
    │   └── LockHeld           another fogiac holds the stack's lock
    ├── CloudError             a target's cloud (its API, or the engine that drives it) said no
    │   ├── CredentialsError   no usable credentials for the target's cloud
    │   └── PreflightError     something would fail before any money is spent
    ├── ProvisionError         a host could not be provisioned
    │   └── HostKeyError       a host presented a key other than the recorded one
    ├── LinkError              the link between the edge and the hosts could not open, or was lost for good
    ├── CertError              a certificate folder or request is unusable
    ├── WorkloadError          a workload's input is unusable
    └── MissingExtra           an optional dependency is not installed

A plug-in's own errors subclass these in its own folder, and it translates its backend's exceptions
(an SDK's, an engine's, a socket's) into them at its edge: a middleware's link errors under
``fogiac/net/<middleware>/errors.py``, a target's cloud and tunnel errors under
``fogiac/targets/<target>/errors.py``. A caller that catches the neutral class catches every plug-in's.
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


class ProvisionError(FogiacError):
    pass


class HostKeyError(ProvisionError):
    pass


class LinkError(FogiacError):
    """What carries topics (or the edge's tunnel) between the edge and the hosts failed for good."""


class CertError(FogiacError):
    pass


class WorkloadError(FogiacError):
    pass


class MissingExtra(FogiacError):
    """An optional dependency is not installed; the message names the extra to install."""
