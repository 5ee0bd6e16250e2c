"""The Pulumi engine's own error, a :class:`~fogiac.errors.CloudError` of the neutral tree: what the
Automation API and the Pulumi CLI fail with is translated into it at the engine's edge, for every cloud
that declares its resources through the engine."""

from __future__ import annotations

from fogiac.errors import CloudError


class EngineError(CloudError):
    """The Pulumi engine is missing or failed."""
