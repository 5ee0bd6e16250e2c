"""The fleet tests run on the relay tests' real roscores and lab certificates."""

from tests.net.relay.conftest import certs, masters, procs, ros_ready

__all__ = ["certs", "masters", "procs", "ros_ready"]
