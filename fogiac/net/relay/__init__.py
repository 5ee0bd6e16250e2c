"""The relay: ROS 1 topics between an edge master and a cloud master over one mutual-TLS
connection that the edge opens (cloud machines cannot dial the robot through Client VPN).

Use in-process (``with CloudRelay(cfg):`` / ``EdgeRelay(cfg).start()``) or as
``fogiac relay cloud|edge`` processes; :func:`read_stats` reads what a process reports.
Modules: ``framing`` and ``tcpros`` (pure codecs), ``rosapi`` (master/slave XML-RPC),
``graph`` (discovery, pure), ``queues``, ``compression``, ``stats``, ``monitor``,
``node``/``pubsub`` (the relay as a ROS node), ``session`` (one link), ``edge``, ``cloud``.
"""

from __future__ import annotations

from fogiac.net.relay.config import RELAY_PORT, CloudConfig, EdgeConfig
from fogiac.net.relay.graph import TopicPolicy
from fogiac.net.relay.stats import RelayStats, TopicStats, read_stats

__all__ = [
    "RELAY_PORT", "CloudConfig", "CloudRelay", "EdgeConfig", "EdgeRelay", "RelayStats", "TopicPolicy",
    "TopicStats", "read_stats",
]


def __getattr__(name: str) -> object:
    """The ends import sockets and ssl: load them only when asked for."""
    if name == "EdgeRelay":
        from fogiac.net.relay.edge import EdgeRelay

        return EdgeRelay
    if name == "CloudRelay":
        from fogiac.net.relay.cloud import CloudRelay

        return CloudRelay
    raise AttributeError(name)
