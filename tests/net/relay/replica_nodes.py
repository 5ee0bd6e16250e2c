"""rospy nodes for the replica tests and benchmark: a robot asking, and a node answering (one per process).

    python replica_nodes.py echo REQ REPLY --name NAME [--work-ms W] [--pad BYTES] [--definition TEXT]
    python replica_nodes.py robot REQ REPLY --count N [--rate HZ] [--base B] [--wait S] [--seq-base Q] [--go FILE]

Both topics carry ``std_msgs/Header``. ``echo`` answers each request with a Header of the same seq
and stamp and ``frame_id`` NAME, after W ms of CPU work (a busy loop, so a CPU quota or a stop
slows it; ``--name ip``: this host's global IPv4 address, for replicas that run one command on
several hosts; ``--pad``: that many random characters after a ``|`` in ``frame_id``, a reply big enough
for a slow link to delay; ``--definition``: the message definition its publisher sends, a hostile replica's).
``robot`` waits until someone subscribes to REQ and publishes to REPLY, sends N requests (seq Q+i, stamp
base+i s; ``--zero-stamp``: stamp 0, and replies told apart by seq), and prints one JSON line per reply
it gets: {"i", "from", "ms", "seq", "nsecs"} (ms: from its send to the reply's arrival; seq and nsecs as the reply
carries them: with ``--seq-base`` robots sending equal stamps tell whose request a reply answers), then ``done``.
With ``--go``, it prints ``connected`` once linked and sends only once FILE exists (robots that start together).
"""

from __future__ import annotations

import argparse
import json
import os
import secrets
import subprocess
import threading
import time


def _host_address() -> str:
    """This host's (network namespace's) global IPv4 address."""
    out = subprocess.run(["ip", "-4", "-o", "addr", "show", "scope", "global"], capture_output=True, text=True).stdout
    return out.split()[3].split("/")[0]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("role", choices=["echo", "robot"])
    parser.add_argument("request")
    parser.add_argument("reply")
    parser.add_argument("--name", default="echo")
    parser.add_argument("--work-ms", type=float, default=0.0)
    parser.add_argument("--pad", type=int, default=0, help="echo: random characters added to each reply")
    parser.add_argument("--count", type=int, default=100)
    parser.add_argument("--rate", type=float, default=20.0)
    parser.add_argument("--base", type=int, default=1000, help="robot: request i is stamped base + i seconds")
    parser.add_argument("--wait", type=float, default=10.0, help="robot: how long to wait for the last replies")
    parser.add_argument("--definition", default=None,
                        help="echo: the message definition its publisher sends (a hostile replica's), not Header's")
    parser.add_argument("--zero-stamp", action="store_true", help="robot: every request stamped 0, told apart by seq")
    parser.add_argument("--seq-base", type=int, default=0, help="robot: request i carries seq Q + i")
    parser.add_argument("--go", default=None, help="robot: once linked, wait for this file before sending")
    args = parser.parse_args()

    import rospy
    from std_msgs.msg import Header

    rospy.init_node(f"replica_{args.role}", anonymous=True, disable_signals=True)
    if args.role == "echo":
        name = _host_address() if args.name == "ip" else args.name
        if args.pad:
            name += "|" + secrets.token_urlsafe(args.pad)[:args.pad]  # random: the relay's compression keeps it big
        if args.definition is not None:  # what rospy sends in its connection header as message_definition
            Header._full_text = args.definition.replace("\\n", "\n")
        pub = rospy.Publisher(args.reply, Header, queue_size=100)

        def answer(req: Header) -> None:
            end = time.perf_counter() + args.work_ms / 1e3
            while time.perf_counter() < end:
                pass
            pub.publish(Header(seq=req.seq, stamp=req.stamp, frame_id=name))

        rospy.Subscriber(args.request, Header, answer, queue_size=100, tcp_nodelay=True)
        print("ready", flush=True)
        while not rospy.is_shutdown():
            time.sleep(0.2)
        return

    sent: dict[int, float] = {}
    lock = threading.Lock()

    def got(reply: Header) -> None:
        now = time.perf_counter()
        i = reply.seq - args.seq_base if args.zero_stamp else reply.stamp.secs - args.base
        with lock:
            t0 = sent.get(i)
        ms = None if t0 is None else round((now - t0) * 1e3, 3)
        print(json.dumps({"i": i, "from": reply.frame_id.split("|")[0], "ms": ms, "seq": reply.seq,
                          "nsecs": reply.stamp.nsecs}), flush=True)

    pub = rospy.Publisher(args.request, Header, queue_size=100, tcp_nodelay=True)
    sub = rospy.Subscriber(args.reply, Header, got, queue_size=1000, tcp_nodelay=True)
    print("ready", flush=True)
    while (pub.get_num_connections() == 0 or sub.get_num_connections() == 0) and not rospy.is_shutdown():
        time.sleep(0.05)
    if args.go is not None:
        print("connected", flush=True)
        while not os.path.exists(args.go) and not rospy.is_shutdown():
            time.sleep(0.01)
    time.sleep(0.5)
    for i in range(args.count):
        with lock:
            sent[i] = time.perf_counter()
        stamp = rospy.Time(0, 0) if args.zero_stamp else rospy.Time(args.base + i, 0)
        pub.publish(Header(seq=args.seq_base + i, stamp=stamp, frame_id="robot"))
        time.sleep(1.0 / args.rate)
    time.sleep(args.wait)
    print("done", flush=True)


if __name__ == "__main__":
    main()
