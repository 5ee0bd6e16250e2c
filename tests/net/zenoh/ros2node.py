"""A ROS 2 node stood in by zenoh-ros2-sdk, run as its own process (the SDK keeps one session per process).

    python -m tests.net.zenoh.ros2node PORT OUT.jsonl --pub /topic=Type ... --sub /topic=Type ...

It connects to the router on 127.0.0.1:PORT the way an rmw_zenoh node does; with PORT 0 it is told
nothing and finds its router as rmw_zenoh does, from ``ZENOH_CONFIG_OVERRIDE`` (or
``ZENOH_SESSION_CONFIG_URI``) over the default session config. It publishes every
listed topic every 100 ms (message ``seq`` is deterministic: :func:`message`), and appends one JSON
line per message sent or received: ``{"event", "topic", "seq", "sha256"}``, where sha256 is over
the message's CDR bytes. Message definitions are always passed in (the SDK would fetch them from
the internet otherwise), from :data:`DEFINITIONS`.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import random
import signal
import tempfile
import threading
from pathlib import Path
from typing import Any

import numpy as np

# ROS 2's own definitions (rcl_interfaces' builtin_interfaces, common_interfaces' std_msgs and sensor_msgs).
DEFINITIONS = {
    "builtin_interfaces/msg/Time": "int32 sec\nuint32 nanosec\n",
    "std_msgs/msg/Header": "builtin_interfaces/Time stamp\nstring frame_id\n",
    "std_msgs/msg/String": "string data\n",
    "sensor_msgs/msg/Image": (
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\n"
        "uint32 step\nuint8[] data\n"
    ),
}
TYPES = {"String": "std_msgs/msg/String", "Image": "sensor_msgs/msg/Image", "Header": "std_msgs/msg/Header"}
WIDTH, HEIGHT = 640, 480


def message(kind: str, topic: str, seq: int, size: int = 0) -> dict[str, Any]:
    """The fields of message ``seq`` on ``topic``: the same on both sides of the link."""
    if kind == "String":
        text = f"{topic} #{seq} " + "".join(random.Random(seq).choices("abcdefghij", k=size))
        return {"data": text}
    if kind == "Header":  # a request: stamped with its seq, so two robots' requests have equal stamps
        return {"frame_id": f"{topic} #{seq}"}
    data = random.Random(f"{topic}{seq}").randbytes(WIDTH * HEIGHT * 3)
    return {"width": WIDTH, "height": HEIGHT, "encoding": "rgb8", "is_bigendian": 0, "step": WIDTH * 3,
            "data": data, "frame_id": f"seq {seq}"}


def _seq(kind: str, msg: Any) -> int:
    if kind == "Header":
        return int(msg.frame_id.split("#")[1])
    text = msg.data if kind == "String" else msg.header.frame_id
    return int(text.split("#")[1].split()[0]) if kind == "String" else int(text.split()[1])


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("port", type=int)
    parser.add_argument("out", type=Path)
    parser.add_argument("--pub", action="append", default=[])
    parser.add_argument("--sub", action="append", default=[])
    parser.add_argument("--size", type=int, default=64)
    args = parser.parse_args()

    from zenoh_ros2_sdk import ROS2Publisher, ROS2Subscriber
    from zenoh_ros2_sdk.message_registry import get_registry
    from zenoh_ros2_sdk.session import ZenohSession

    messages = Path(tempfile.mkdtemp(prefix="fogiac-msgs-"))
    for name, text in DEFINITIONS.items():
        path = messages / f"{name}.msg"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    get_registry(str(messages))  # local definitions only: never a download
    # PORT 0: the SDK's defaults (rmw_zenoh's session config), which the environment overrides.
    router = {"router_ip": "127.0.0.1", "router_port": args.port} if args.port else {}
    session = ZenohSession.get_instance(**router)
    for name in ("builtin_interfaces/msg/Time", "std_msgs/msg/Header"):
        session.register_message_type(DEFINITIONS[name], name)
    store = session.store

    lock = threading.Lock()
    out = args.out.open("a")

    def record(event: str, topic: str, seq: int, cdr: bytes, text: str | None = None) -> None:
        line = {"event": event, "topic": topic, "seq": seq, "sha256": hashlib.sha256(cdr).hexdigest()}
        with lock:
            out.write(json.dumps(line if text is None else dict(line, text=text)) + "\n")
            out.flush()

    subs = []
    for spec in args.sub:
        topic, kind = spec.split("=")

        def on_message(msg: Any, topic: str = topic, kind: str = kind) -> None:
            cdr = bytes(store.serialize_cdr(msg, TYPES[kind]))
            if kind == "String" and "#" not in msg.data:  # not one of ours (fogiac's /fogros/* figures): keep the text
                record("received", topic, -1, cdr, msg.data)
            elif kind == "Header":  # a reply: whose request it answers (frame_id) and its stamp
                record("received", topic, _seq(kind, msg), cdr, f"{msg.frame_id} @{msg.stamp.sec}.{msg.stamp.nanosec}")
            else:
                record("received", topic, _seq(kind, msg), cdr)

        subs.append(ROS2Subscriber(topic=topic, msg_type=TYPES[kind], msg_definition=DEFINITIONS[TYPES[kind]],
                                   callback=on_message, **router))
    pubs = []
    for spec in args.pub:
        topic, kind = spec.split("=")
        pubs.append((topic, kind, ROS2Publisher(topic=topic, msg_type=TYPES[kind],
                                                msg_definition=DEFINITIONS[TYPES[kind]],
                                                **router)))
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    print("ready", flush=True)
    seq = 0
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    while not stop.wait(0.1):
        for topic, kind, pub in pubs:
            fields = message(kind, topic, seq, args.size)
            if kind == "Header":
                fields = dict(fields, stamp=Time(sec=seq, nanosec=0))
            if kind == "Image":
                fields = dict(fields, header=Header(stamp=Time(sec=seq, nanosec=0), frame_id=fields.pop("frame_id")),
                              data=np.frombuffer(fields["data"], dtype=np.uint8))
            pub.publish(**fields)
            record("sent", topic, seq, bytes(store.serialize_cdr(pub.msg_class(**fields), TYPES[kind])))
        seq += 1
    with lock:  # every line is written whole; the SDK's session threads held a normal exit until the stop's
        out.flush()  # grace ran out and SIGKILL came (5 s per node, most of a fleet test's teardown)
        os._exit(0)


if __name__ == "__main__":
    main()
