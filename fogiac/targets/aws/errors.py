"""The aws target's own errors, subclasses of the neutral tree (:mod:`fogiac.errors`): what
OpenVPN fails with is translated into these at the target's edge; the Pulumi engine's
error is the shared engine's (:mod:`fogiac.pulumi_engine.errors`)."""

from __future__ import annotations

from fogiac.errors import LinkError
from fogiac.pulumi_engine.errors import EngineError

__all__ = ["EngineError", "VpnError"]  # the engine's error, as the aws target raises it


class VpnError(LinkError):
    """OpenVPN (the edge's end of the Client VPN) could not be set up."""
