"""Zenoh publisher / subscriber for the Zenoh benchmark (one session per process, as a ROS 2 node has).

    node.py pub ENDPOINT KEY --size BYTES --rate HZ --duration S   (rate 0: as fast as it can)
    node.py sub ENDPOINT KEY --duration S                          prints one JSON summary line

Both connect as clients to a router at ENDPOINT (``tcp/127.0.0.1:PORT``). The first 16 bytes of
every payload are the sequence number and the publish time (CLOCK_MONOTONIC, shared by every
process on the machine), so the subscriber's latency is its receive time minus that.
"""

from __future__ import annotations

import argparse
import json
import struct
import threading
import time

import zenoh

HEADER = struct.Struct("<QQ")  # seq, publish time (monotonic ns)


def _session(endpoint: str) -> zenoh.Session:
    config = {"mode": "client", "connect": {"endpoints": [endpoint]}, "scouting": {"multicast": {"enabled": False}}}
    return zenoh.open(zenoh.Config.from_json5(json.dumps(config)))


def publish(session: zenoh.Session, key: str, *, size: int, rate: float, duration: float) -> None:
    pub = session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
    deadline = time.monotonic() + 15
    while not pub.matching_status.matching and time.monotonic() < deadline:  # the far subscriber is declared
        time.sleep(0.05)
    buf = bytearray(max(size, HEADER.size))
    period = 1.0 / rate if rate else 0.0
    end = time.monotonic() + duration
    seq = 0
    next_at = time.monotonic()
    while time.monotonic() < end:
        HEADER.pack_into(buf, 0, seq, time.monotonic_ns())
        pub.put(bytes(buf))
        seq += 1
        if period:
            next_at += period
            time.sleep(max(0.0, next_at - time.monotonic()))
    time.sleep(1.0)  # let the last messages drain before the session closes
    pub.undeclare()


def subscribe(session: zenoh.Session, key: str, *, duration: float) -> list[tuple[float, float, int, int]]:
    arrivals: list[tuple[float, float, int, int]] = []  # recv time s, latency s, bytes, seq
    first = threading.Event()

    def on_sample(sample: zenoh.Sample) -> None:
        now = time.monotonic_ns()
        data = sample.payload.to_bytes()
        seq, sent = HEADER.unpack_from(data)
        arrivals.append((now / 1e9, (now - sent) / 1e9, len(data), seq))
        first.set()

    sub = session.declare_subscriber(key, on_sample)
    print("ready", flush=True)
    first.wait(60)
    time.sleep(duration)
    sub.undeclare()
    return arrivals


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("role", choices=["pub", "sub"])
    parser.add_argument("endpoint")
    parser.add_argument("key")
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--rate", type=float, default=50.0)
    parser.add_argument("--duration", type=float, default=5.0)
    args = parser.parse_args()
    session = _session(args.endpoint)
    try:
        if args.role == "pub":
            publish(session, args.key, size=args.size, rate=args.rate, duration=args.duration)
        else:
            print(json.dumps({"arrivals": subscribe(session, args.key, duration=args.duration)}), flush=True)
    finally:
        session.close()


if __name__ == "__main__":
    main()
