"""The aws target's own errors, subclasses of the neutral tree (:mod:`fogiac.errors`): what the
Pulumi engine and OpenVPN fail with is translated into these at the target's edge."""

from __future__ import annotations

from fogiac.errors import CloudError, LinkError


class EngineError(CloudError):
    """The Pulumi engine is missing or failed."""


class VpnError(LinkError):
    """OpenVPN (the edge's end of the Client VPN) could not be set up."""
