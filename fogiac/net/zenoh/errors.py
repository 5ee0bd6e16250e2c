"""Zenoh's own error: a :class:`~fogiac.errors.LinkError`, so a caller that knows only the neutral tree
catches it; a router's bad config, certificate or port is raised as this one."""

from __future__ import annotations

from fogiac.errors import LinkError


class ZenohError(LinkError):
    """A Zenoh router could not open (bad config, certificate, port)."""
