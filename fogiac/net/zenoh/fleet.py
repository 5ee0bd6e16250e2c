"""A shared request/reply node in a fleet over Zenoh: every robot's requests in, each reply to its own robot.

A fleet's cloud router lets each robot's edge router cross only the keys of its namespace
(:func:`fogiac.net.zenoh.config.fleet_access_control`): robot ``r1`` asks on ``/r1/<request>`` and hears on
``/r1/<reply>``. The shared node is one ROS 2 node on plain topics (``/<request>``, ``/<reply>``). This process,
on the node's host and its loopback router, carries each robot's request to the plain key and the node's
reply back to the robot that asked, and to no other.

A reply names its request by its ``header.stamp`` (as :mod:`fogiac.net.zenoh.replicas`: a CDR message whose
first field is its ``std_msgs/Header``). Two robots may send equal stamps; so the key of a request in flight
is the stamp the node sees, and that is unique: a request whose stamp is already waiting for a reply (from any
robot) is handed to the node with the next free stamp (1 ns later), and its reply gets the robot's own stamp
back. The robot sees exactly the stamp it sent; the node sees a stamp moved by nanoseconds only when two
requests in flight share one. A reply whose stamp no request waits for (answered already, or from before this
process) reaches no robot: it is counted (``unmatched``), never guessed.

    python -m fogiac.net.zenoh.fleet ROUTER --robot r1 --robot r2 --request /plan_request --reply /plan_result

Deployed by ``fogiac up`` (:mod:`fogiac.net.zenoh.deploy`), it takes its robots from the host's fleet file
instead (``--fleet-file F --node NAME``: the robots the node serves, less the revoked ones), and follows it:
a robot added, removed or revoked changes whose requests it carries within a second, and it keeps running.
"""

from __future__ import annotations

import argparse
import json
import logging
import signal
import struct
import sys
import threading
from collections import OrderedDict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from fogiac.extras import need
from fogiac.net.zenoh.errors import ZenohError

log = logging.getLogger(__name__)
FOLLOW_S = 1.0  # how often the fleet file is looked at
MAX_PENDING = 4096  # requests in flight remembered; the oldest is forgotten (its reply then reaches no robot)
_NS = 1_000_000_000


def _stamp(payload: bytes) -> tuple[str, int, int] | None:
    """(byte order, sec, nanosec) of a CDR message's header stamp (after the 4-byte encapsulation header)."""
    if len(payload) < 12:
        return None
    order = "<" if payload[1] & 1 else ">"  # CDR_LE / PL_CDR_LE have the low bit of the kind set
    sec, nanosec = struct.unpack_from(order + "iI", payload, 4)
    return order, sec, nanosec


def _restamp(payload: bytes, order: str, sec: int, nanosec: int) -> bytes:
    data = bytearray(payload)
    struct.pack_into(order + "iI", data, 4, sec, nanosec)
    return bytes(data)


class FleetMux:
    """Requests ``/<robot>/<request>`` -> ``/<request>``; replies ``/<reply>`` -> ``/<robot>/<reply>`` of the
    robot whose request it answers. ``robots``: the robots the node serves (any other robot's requests it never
    passes on); ``fleet``/``node``: taken from the fleet file instead (:meth:`follow`)."""

    def __init__(self, router: str, robots: Sequence[str], *, requests: Sequence[str], replies: Sequence[str],
                 fleet: Path | None = None, node: str = "") -> None:
        if not robots and fleet is None:
            raise ZenohError("a shared node serves at least one robot")
        self.router, self.robots = router, frozenset(robots)
        self.fleet, self.node, self.seen = fleet, node, b""
        self.requests, self.replies = tuple(t.strip("/") for t in requests), tuple(t.strip("/") for t in replies)
        self.pending: OrderedDict[tuple[int, int], tuple[str, int, int]] = OrderedDict()  # node's stamp -> robot's
        self.lock = threading.Lock()
        self.forwarded = self.answered = self.unmatched = self.restamped = 0
        self.session: Any = None
        self.subscribers: dict[str, list[Any]] = {}  # robot -> its request subscribers

    def start(self) -> None:
        zenoh = need("zenoh", extra="ros2")
        config = {"mode": "client", "connect": {"endpoints": [self.router]},
                  "scouting": {"multicast": {"enabled": False}}}
        try:
            self.session = zenoh.open(zenoh.Config.from_json5(json.dumps(config)))
        except zenoh.ZError as err:
            raise ZenohError(f"cannot open a Zenoh session on {self.router}: {err}") from None
        self.follow()
        self._subscribe()
        for topic in self.replies:  # <domain>/<topic>/<type>/<hash>: the node's plain reply, never a robot's
            self.session.declare_subscriber(f"*/{topic}/*/*", lambda s, t=topic: self._reply(t, s))

    def follow(self) -> None:
        """Take the served robots from the fleet file when it changed: the node's entry's robots, less the revoked;
        a file that cannot be read leaves them as they were."""
        if self.fleet is None:
            return
        try:
            data = self.fleet.read_bytes()
            if data == self.seen:
                return
            doc = json.loads(data)
            shared = [s for s in doc.get("shared", []) if s.get("node") == self.node]
            served = {str(r) for s in shared for r in s.get("robots", [])} - {str(r) for r in doc.get("revoked", [])}
        except (OSError, ValueError, AttributeError, TypeError) as err:
            log.warning("%s: %s; the robots of before stand", self.fleet, err)
            return
        with self.lock:
            self.robots, self.seen = frozenset(served), data
        if self.session is not None:
            self._subscribe()

    def _subscribe(self) -> None:
        """One subscriber per served robot and request topic, ``<domain>/<robot>/<topic>/<type>/<hash>``: exactly
        that robot's request. Each within the robot's namespace, so its router carries it across to the robot's
        edge (a wildcard over every robot's would be no robot's to let through); a robot no longer served has its
        subscribers undeclared."""
        with self.lock:
            robots = set(self.robots)
        for robot in sorted(set(self.subscribers) - robots):
            for subscriber in self.subscribers.pop(robot):
                subscriber.undeclare()
        for robot in sorted(robots - set(self.subscribers)):
            self.subscribers[robot] = [
                self.session.declare_subscriber(f"*/{robot}/{topic}/*/*", lambda s, t=topic: self._request(t, s))
                for topic in self.requests]

    def _request(self, topic: str, sample: Any) -> None:
        chunks = str(sample.key_expr).split("/")
        robot = chunks[1]
        with self.lock:
            if robot not in self.robots:  # not a robot this node serves (or one revoked): never passed on
                return
        payload = bytes(sample.payload.to_bytes())
        stamp = _stamp(payload)
        key = "/".join([chunks[0], *chunks[2:]])  # the robot's namespace chunk dropped
        if stamp is None:
            log.warning("a request on /%s/%s without a header stamp: not passed on", robot, topic)
            return
        order, sec, nanosec = stamp
        with self.lock:
            seen = (sec, nanosec)
            while seen in self.pending:  # another request in flight has this stamp: the next free nanosecond
                total = seen[0] * _NS + seen[1] + 1
                seen = (total // _NS, total % _NS)
            if seen != (sec, nanosec):
                payload = _restamp(payload, order, *seen)
                self.restamped += 1
            self.pending[seen] = (robot, sec, nanosec)
            while len(self.pending) > MAX_PENDING:
                self.pending.popitem(last=False)
            self.forwarded += 1
        self.session.put(key, payload, encoding=sample.encoding, attachment=sample.attachment)

    def _reply(self, topic: str, sample: Any) -> None:
        payload = bytes(sample.payload.to_bytes())
        stamp = _stamp(payload)
        with self.lock:
            asked = None if stamp is None else self.pending.pop((stamp[1], stamp[2]), None)
            if asked is None:
                self.unmatched += 1
                return
            self.answered += 1
        robot, sec, nanosec = asked
        assert stamp is not None
        if (sec, nanosec) != (stamp[1], stamp[2]):
            payload = _restamp(payload, stamp[0], sec, nanosec)
        chunks = str(sample.key_expr).split("/")
        key = "/".join([chunks[0], robot, *chunks[1:]])
        self.session.put(key, payload, encoding=sample.encoding, attachment=sample.attachment)

    def stop(self) -> None:
        if self.session is not None:
            self.session.close()


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m fogiac.net.zenoh.fleet")
    parser.add_argument("router", help="the host's router, e.g. tcp/127.0.0.1:7447")
    parser.add_argument("--robot", action="append", default=[], help="a robot the node serves (its namespace)")
    parser.add_argument("--fleet-file", type=Path, help="the host's fleet file: the robots come from it, followed")
    parser.add_argument("--node", default="", help="with --fleet-file: the shared node whose robots to serve")
    parser.add_argument("--request", action="append", required=True, help="a topic the node takes requests on")
    parser.add_argument("--reply", action="append", required=True, help="a topic the node replies on")
    args = parser.parse_args(argv)
    if not args.robot and args.fleet_file is None:
        parser.error("give --robot (at least one) or --fleet-file")
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    mux = FleetMux(args.router, args.robot, requests=args.request, replies=args.reply, fleet=args.fleet_file,
                   node=args.node)
    try:
        mux.start()
    except ZenohError as err:
        print(f"error: {err}", file=sys.stderr)
        sys.exit(1)
    print("ready", flush=True)
    try:
        while not stop.wait(FOLLOW_S):
            mux.follow()
    finally:
        mux.stop()


if __name__ == "__main__":
    main()
