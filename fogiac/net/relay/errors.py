"""The relay's own error: a :class:`~fogiac.errors.LinkError`, so a caller that knows only the neutral
tree catches it; socket, TLS and codec failures inside the relay are raised as this one."""

from __future__ import annotations

from fogiac.errors import LinkError


class RelayError(LinkError):
    """The relay could not start or lost its peer for good."""
