"""A per-robot ROS 2 node stood in on plain Zenoh keys, as rmw_zenoh lays them out: SLAM-like, it keeps state.

    python -m tests.net.zenoh.slamnode [--in /scan] [--out /slam/count] [--log FOLDER] --ros-args -r __ns:=/r1 \
        -r /scan:=/r1/scan -r /slam/count:=/r1/slam/count

It reads ROS 2's own arguments as ``serve: per_robot`` gives them (``--ros-args``, ``-r``/``--remap``
``FROM:=TO``, ``__ns:=``), finds the host's router in ``FOGIAC_ZENOH_ROUTER`` (fogiac's node environment), and
answers every message on its (remapped) input with a ``std_msgs/Header`` on its (remapped) output: the stamp
kept, the frame id ``<namespace>|<count>|<the message's frame id>``, ``count`` being how many messages this
instance has seen. With ``--log``, every message it counts is also a JSON line in ``FOLDER/<namespace>.jsonl``
(its pid, count, key and frame id): the test reads an instance's state there, whatever reached the robot.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import struct
import threading
from pathlib import Path

import zenoh


def ros_args(argv: list[str]) -> tuple[str, dict[str, str]]:
    """(namespace, topic remaps) from ROS 2's ``--ros-args`` blocks (each runs to ``--`` or the end)."""
    namespace, remaps, inside, take = "/", {}, False, False
    for arg in argv:
        if arg == "--ros-args":
            inside = True
        elif arg == "--":
            inside = False
        elif inside and arg in ("-r", "--remap"):
            take = True
        elif take:
            take = False
            source, _, target = arg.partition(":=")
            if source == "__ns":
                namespace = target
            else:
                remaps[source] = target
    return namespace, remaps


def _header(payload: bytes, frame_id: str) -> bytes:
    """``payload``'s CDR header (encapsulation and stamp) with ``frame_id`` in place of its own."""
    text = frame_id.encode() + b"\0"
    return payload[:12] + struct.pack("<I", len(text)) + text


def _frame_id(payload: bytes) -> str:
    (size,) = struct.unpack_from("<I", payload, 12)
    return payload[16:16 + size - 1].decode(errors="replace")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--in", dest="inp", default="/scan")
    parser.add_argument("--out", default="/slam/count")
    parser.add_argument("--log", type=Path)
    args, rest = parser.parse_known_args()
    namespace, remaps = ros_args(rest)
    source, target = remaps.get(args.inp, args.inp).strip("/"), remaps.get(args.out, args.out).strip("/")
    router = os.environ["FOGIAC_ZENOH_ROUTER"]
    config = {"mode": "client", "connect": {"endpoints": [router]}, "scouting": {"multicast": {"enabled": False}}}
    session = zenoh.open(zenoh.Config.from_json5(json.dumps(config)))
    log = None
    if args.log is not None:
        args.log.mkdir(parents=True, exist_ok=True)
        log = (args.log / f"{namespace.strip('/') or 'root'}.jsonl").open("a")
    lock = threading.Lock()
    seen: list[str] = []  # this instance's own state: every message it has counted

    def answer(sample: zenoh.Sample) -> None:
        payload = sample.payload.to_bytes()
        if len(payload) < 16:
            return
        domain, *_, kind, digest = str(sample.key_expr).split("/")
        with lock:
            seen.append(_frame_id(payload))
            count = len(seen)
            if log is not None:
                log.write(json.dumps({"pid": os.getpid(), "count": count, "key": str(sample.key_expr),
                                      "frame_id": seen[-1]}) + "\n")
                log.flush()
        reply = _header(payload, f"{namespace}|{count}|{seen[-1]}")
        session.put(f"{domain}/{target}/{kind}/{digest}", reply, encoding=sample.encoding,
                    attachment=sample.attachment)

    session.declare_subscriber(f"*/{source}/*/*", answer)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    print(f"slam up in {namespace}: /{source} -> /{target}", flush=True)
    stop.wait()
    session.close()


if __name__ == "__main__":
    main()
