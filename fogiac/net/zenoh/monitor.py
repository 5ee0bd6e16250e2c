"""``/fogros/latency`` and ``/fogros/throughput`` for ROS 2: measured at the edge, published as ROS 2 topics.

The edge monitor is one Zenoh session on the edge router. It subscribes to every manifest topic
(rmw_zenoh's data keys, :func:`fogiac.net.zenoh.config.topic_key`) and once a period publishes two
``std_msgs/msg/String`` messages holding one compact JSON object each, the same shapes the ROS 1
relay publishes, so ``ros2 topic echo /fogros/latency`` or any node reads them without custom types:

    /fogros/latency     {"role":"edge","topics":{"/t":{"direction","median_ms","p99_ms"}}}
    /fogros/throughput  {"role":"edge","topics":{"/t":{"direction","msgs_per_s","bytes_per_s","msgs","bytes",...}}}

``direction`` "in": the topic arrives from the cloud; its latency is the time from the rmw_zenoh
attachment's source timestamp (the publisher's clock) to arrival here, so across machines it
includes their clock offset (EC2 hosts keep Amazon Time Sync; keep the robot on NTP too). "out":
the robot publishes it towards the cloud; counted, no latency. Messages are put under rmw_zenoh's
key expression with CDR encoding and an rmw_zenoh attachment, and only while someone subscribes.
"""

from __future__ import annotations

import argparse
import json
import signal
import struct
import sys
import threading
import time
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

from fogiac.extras import need
from fogiac.net.relay.stats import TopicCounters, TopicStats
from fogiac.net.zenoh.config import topic_key
from fogiac.net.zenoh.errors import ZenohError
from fogiac.state import write_json_atomic

LATENCY_TOPIC = "/fogros/latency"
THROUGHPUT_TOPIC = "/fogros/throughput"
# std_msgs/msg/String as rmw_zenoh names it: DDS type name and REP-2011 type hash (RIHS01).
STRING_TYPE = "std_msgs::msg::dds_::String_"
STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
_CDR_LE = b"\x00\x01\x00\x00"  # CDR encapsulation header: plain CDR, little endian
_ATTACHMENT = struct.Struct("<QQ")  # rmw_zenoh attachment: sequence number, source timestamp (ns), then the gid


def string_cdr(text: str) -> bytes:
    """A serialized std_msgs/msg/String: CDR header, uint32 length with the NUL, the bytes, NUL."""
    data = text.encode() + b"\x00"
    return _CDR_LE + struct.pack("<I", len(data)) + data


def data_key(topic: str, *, domain: int = 0) -> str:
    return f"{domain}/{topic.strip('/')}/{STRING_TYPE}/{STRING_HASH}"


def attachment(seq: int, stamp_ns: int, gid: bytes) -> bytes:
    return _ATTACHMENT.pack(seq, stamp_ns) + bytes([len(gid)]) + gid


def source_stamp(raw: bytes | None) -> int | None:
    """The source timestamp (ns since the epoch) of an rmw_zenoh attachment, or None without one."""
    if raw is None or len(raw) < _ATTACHMENT.size:
        return None
    return _ATTACHMENT.unpack_from(raw)[1]


def latency_doc(stats: Sequence[TopicStats]) -> dict[str, Any]:
    return {"role": "edge", "topics": {t.topic: {"direction": t.direction, "median_ms": t.latency_ms,
                                                 "p99_ms": t.latency_p99_ms} for t in stats}}


def throughput_doc(stats: Sequence[TopicStats]) -> dict[str, Any]:
    return {"role": "edge", "topics": {t.topic: {"direction": t.direction, "msgs_per_s": t.msgs_per_s,
                                                 "bytes_per_s": t.bytes_per_s, "msgs": t.msgs, "bytes": t.bytes}
                                       for t in stats}}


class EdgeMonitor:
    """Counts the manifest's topics on the edge router and publishes the figures as ROS 2 topics."""

    def __init__(self, session: Any, *, to_edge: Sequence[str], to_cloud: Sequence[str], domain: int = 0) -> None:
        self._counters = {t: TopicCounters(t, "in", "none") for t in sorted(set(to_edge))}
        self._counters |= {t: TopicCounters(t, "out", "none") for t in sorted(set(to_cloud)) if t not in self._counters}
        self._lock = threading.Lock()
        self._subs = [session.declare_subscriber(topic_key(t), self._sampler(c)) for t, c in self._counters.items()]
        self._pubs = [(session.declare_publisher(data_key(LATENCY_TOPIC, domain=domain)), latency_doc),
                      (session.declare_publisher(data_key(THROUGHPUT_TOPIC, domain=domain)), throughput_doc)]
        self._gid = bytes.fromhex(str(session.zid()).rjust(32, "0"))[-16:]  # rmw_zenoh gids are 16 bytes
        self._seq = 0
        self.published = 0  # messages built and sent; stays 0 while nobody listens

    def _sampler(self, counters: TopicCounters) -> Any:
        def on_sample(sample: Any) -> None:
            now = time.time_ns()
            raw = sample.attachment
            stamp = source_stamp(raw.to_bytes() if raw is not None else None)
            latency = now - stamp if stamp is not None and counters.direction == "in" else None
            with self._lock:
                counters.count(len(sample.payload), latency)

        return on_sample

    def tick(self) -> tuple[TopicStats, ...]:
        """Turn the last period's counts into rates and publish them to whoever listens."""
        with self._lock:
            for counters in self._counters.values():
                counters.tick()
            stats = tuple(c.snapshot() for c in self._counters.values())
        for pub, doc in self._pubs:
            if pub.matching_status.matching:
                text = json.dumps(doc(stats), separators=(",", ":"))
                pub.put(string_cdr(text), encoding="application/cdr",
                        attachment=attachment(self._seq, time.time_ns(), self._gid))
                self._seq += 1
                self.published += 1
        return stats

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        for pub, _ in self._pubs:
            pub.undeclare()


def open_client(endpoint: str) -> Any:
    """A client session on the router at ``endpoint`` (the edge router's loopback port)."""
    zenoh = need("zenoh", extra="ros2")
    # Waits for the router (retrying), so a supervisor may start both at once.
    config = {"mode": "client", "connect": {"endpoints": [endpoint], "timeout_ms": -1},
              "scouting": {"multicast": {"enabled": False}}}
    try:
        return zenoh.open(zenoh.Config.from_json5(json.dumps(config)))
    except zenoh.ZError as err:
        raise ZenohError(f"zenoh monitor: {endpoint}: {err}") from None


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m fogiac.net.zenoh.monitor", description=__doc__.split("\n")[0])
    parser.add_argument("endpoint", help="the edge router's local endpoint, e.g. tcp/127.0.0.1:7447")
    parser.add_argument("--to-edge", action="append", default=[], help="a topic the cloud publishes")
    parser.add_argument("--to-cloud", action="append", default=[], help="a topic the robot publishes")
    parser.add_argument("--period", type=float, default=1.0)
    parser.add_argument("--domain", type=int, default=0, help="ROS_DOMAIN_ID")
    parser.add_argument("--stats-file", type=Path, help="also write each period's figures here (for status)")
    args = parser.parse_args(argv)
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    session = open_client(args.endpoint)
    monitor = EdgeMonitor(session, to_edge=args.to_edge, to_cloud=args.to_cloud, domain=args.domain)
    print("ready", flush=True)
    try:
        while not stop.wait(args.period):
            stats = monitor.tick()
            if args.stats_file is not None:
                write_json_atomic(args.stats_file, {"topics": [asdict(t) for t in stats]})
    finally:
        monitor.close()
        session.close()


if __name__ == "__main__":
    try:
        main()
    except ZenohError as err:
        print(f"error: {err}", file=sys.stderr)
        sys.exit(1)
