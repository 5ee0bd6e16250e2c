"""The relay: ROS 1 topics between an edge master and a cloud master over one mutual-TLS
connection that the edge opens (cloud machines cannot dial the robot through Client VPN).

Use in-process (``with CloudRelay(cfg):`` / ``EdgeRelay(cfg).start()``) or as
``fogiac relay cloud|edge`` processes; :func:`read_stats` reads what a process reports.
Modules: ``framing`` and ``tcpros`` (pure codecs), ``rosapi`` (master/slave XML-RPC),
``graph`` (discovery, pure), ``queues``, ``compression``, ``stats``, ``monitor``,
``node``/``pubsub`` (the relay as a ROS node), ``session`` (one link), ``edge``, ``cloud``.
"""

from __future__ import annotations

from fogiac.middlewares import MiddlewareEntry
from fogiac.net.relay.config import RELAY_PORT, CloudConfig, EdgeConfig
from fogiac.net.relay.graph import TopicPolicy
from fogiac.net.relay.stats import RelayStats, TopicStats, read_stats

__all__ = [
    "RELAY_PORT", "CloudConfig", "CloudRelay", "EdgeConfig", "EdgeRelay", "RelayStats", "TopicPolicy",
    "TopicStats", "read_stats",
]


def __getattr__(name: str) -> object:
    """The ends load ssl, cryptography's x509 and xmlrpc.server (~70 ms): only when asked for.

    The middleware registry imports this package's ``middleware`` module while a manifest is validated,
    so eager imports here would slow every ``fogiac validate``.
    """
    if name == "EdgeRelay":
        from fogiac.net.relay.edge import EdgeRelay  # noqa: PLC0415 (lazy on purpose, see above)

        return EdgeRelay
    if name == "CloudRelay":
        from fogiac.net.relay.cloud import CloudRelay  # noqa: PLC0415 (lazy on purpose, see above)

        return CloudRelay
    raise AttributeError(name)

ENTRY = MiddlewareEntry(name="relay", middleware="fogiac.net.relay.middleware:RELAY",
                        deployment="fogiac.net.relay.deploy:DEPLOYMENT")
