"""``/fogros/latency`` and ``/fogros/throughput``: the relay's figures as ROS topics.

Both are ``std_msgs/String`` carrying one compact JSON object, so ``rostopic echo`` or any
node reads them without custom message types:

    /fogros/latency     {"role","connected","rtt_ms","clock_offset_ms",
                         "topics":{"/t":{"direction","median_ms","p99_ms"}}}
    /fogros/throughput  {"role","connected","reconnects",
                         "topics":{"/t":{"direction","msgs_per_s","bytes_per_s","msgs","bytes","drops","compression"}}}

Latency is one-way, from the moment the sending end read the message off its local publisher
to the moment the receiving end read it off the link, with the peers' clock offset removed;
it appears on the receiving end (``direction`` "in"). Messages are built and sent only while
someone is subscribed to them.
"""

from __future__ import annotations

import json
import struct
from typing import Any

from fogiac.net.relay.node import RelayNode
from fogiac.net.relay.pubsub import LocalPublisher, TopicMeta
from fogiac.net.relay.stats import RelayStats

LATENCY_TOPIC = "/fogros/latency"
THROUGHPUT_TOPIC = "/fogros/throughput"
STRING = TopicMeta("std_msgs/String", "992ce8a1687cec8c8bd883ec73ca41d1", "string data\n", latching=False)


def string_msg(text: str) -> bytes:
    """A serialized std_msgs/String."""
    data = text.encode()
    return struct.pack("<I", len(data)) + data


def latency_doc(stats: RelayStats) -> dict[str, Any]:
    return {
        "role": stats.role, "connected": stats.connected, "rtt_ms": stats.rtt_ms,
        "clock_offset_ms": stats.clock_offset_ms,
        "topics": {t.topic: {"direction": t.direction, "median_ms": t.latency_ms, "p99_ms": t.latency_p99_ms}
                   for t in stats.topics},
    }


def throughput_doc(stats: RelayStats) -> dict[str, Any]:
    return {
        "role": stats.role, "connected": stats.connected, "reconnects": stats.reconnects,
        "topics": {t.topic: {"direction": t.direction, "msgs_per_s": t.msgs_per_s, "bytes_per_s": t.bytes_per_s,
                             "msgs": t.msgs, "bytes": t.bytes, "drops": t.drops, "compression": t.compression}
                   for t in stats.topics},
    }


class Monitor:
    def __init__(self, node: RelayNode) -> None:
        self._latency = LocalPublisher(node, LATENCY_TOPIC, STRING, depth=2)
        self._throughput = LocalPublisher(node, THROUGHPUT_TOPIC, STRING, depth=2)
        self.published = 0  # messages built and sent; stays 0 while nobody listens

    def start(self) -> None:
        self._latency.start()
        self._throughput.start()

    def publish(self, stats: RelayStats) -> None:
        for pub, doc in ((self._latency, latency_doc), (self._throughput, throughput_doc)):
            if pub.has_subscribers:
                pub.publish(string_msg(json.dumps(doc(stats), separators=(",", ":"))))
                self.published += 1

    def stop(self) -> None:
        self._latency.stop()
        self._throughput.stop()
