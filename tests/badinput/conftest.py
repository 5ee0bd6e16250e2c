"""The relay's fixtures (two roscores, a certificate bundle, process cleanup) for the peer cases."""

from __future__ import annotations

from tests.net.relay.conftest import certs, masters, procs, ros_ready

__all__ = ["certs", "masters", "procs", "ros_ready"]
