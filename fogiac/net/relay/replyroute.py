"""A fleet's shared request/reply node: each reply goes back only to the robot whose request it answers. Pure.

The cloud end is one ROS node for every robot it links (:mod:`.shared`): the robots' requests reach the
shared node through one publisher, and the node's replies come back through one subscription. Without this
module every robot subscribed to the reply topic would get every reply, its neighbours' included. So the
cloud end remembers, per shared node (a :class:`~fogiac.net.relay.fleet.SharedPair` of the access file),
which robot sent each request still waiting for its reply, by the key the reply will carry: the field the
manifest's ``reply_match`` names (:mod:`.match`; ``header.stamp`` by default, the replicas' key). It is the
mirror image of the replicas' :class:`~fogiac.net.replicas.Merge` (one robot, many servers there; many
robots, one server here).

Two robots may send requests with equal keys (two arms stamping with synchronised clocks, or both starting
their counters at 0), and the reply carries the key only, not the robot. So what is remembered is the pair
(robot, key), and the keys the node sees are kept apart:

- with ``header.stamp`` (a fixed place, bytes 4..12 of the message), a request whose stamp is already
  waiting for a reply (from any robot) is handed to the node with the next free stamp (a nanosecond later),
  and its reply gets the robot's own stamp back before it leaves: the robot sees exactly the stamp it sent,
  each reply is found by a stamp no other request in flight has, whatever order the node answers in
  (as :mod:`fogiac.net.zenoh.fleet` does over Zenoh);
- with any other field (``id``, ``request.uuid``...: a string or nested field is not moved in place), the
  requests waiting with one key are queued in arrival order, and a reply with that key answers the oldest
  of them: right for a node that answers one topic's requests in the order they come (rospy and roscpp's
  single-threaded spinner do; the relay hands the node every robot's requests through one connection).

A reply whose key no waiting request has (answered already, expired, from before the cloud end started, or
junk) reaches no robot: it is dropped and counted (``unmatched``), never guessed. A request without a key
(too short, or a field its type lacks) is not passed on (``keyless``): no reply to it could be routed. A
shared node with several reply topics answers each request once on each of them. Memory is bounded: at most
``pending`` requests of each robot wait per shared node (that robot's oldest is forgotten first, so a robot
that floods the node forgets only its own requests) and none longer than ``expire_s``; a reply to a
forgotten request is unmatched. A shared node with no key (``match: null``) is
not routed: its outputs go to every robot that subscribes them, which the access rules limit to the robots
it serves.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from fogiac.net.relay.fleet import SharedPair
from fogiac.net.relay.framing import Payload
from fogiac.net.relay.match import DEFAULT_MATCH, Key, KeyOf

PENDING = 4096  # requests of one robot waiting for a reply, per shared node
EXPIRE_S = 60.0  # how long a request waits for its reply before it is forgotten
_NS = 1_000_000_000
_STAMP = slice(4, 12)  # header.stamp in a ROS 1 message that begins with its std_msgs/Header


def _next_stamp(key: Key) -> Key:
    """The stamp one nanosecond after ``key`` (uint32 secs, uint32 nsecs, little-endian)."""
    total = int.from_bytes(key[:4], "little") * _NS + int.from_bytes(key[4:], "little") + 1
    secs, nsecs = divmod(total, _NS)
    return (secs % 2**32).to_bytes(4, "little") + nsecs.to_bytes(4, "little")


def _with_stamp(data: Payload, stamp: Key) -> bytes:
    raw = bytearray(data)
    raw[_STAMP] = stamp
    return bytes(raw)


@dataclass(slots=True)
class _Asked:
    robot: str
    key: Key  # as the node sees it
    own: Key  # as the robot sent it
    at: float
    waiting: frozenset[str]  # reply topics that have not answered it yet (the pair's own set at first: no copy)


@dataclass
class _Node:
    """One shared node's waiting requests, in arrival order, and by the key the node sees."""

    pair: SharedPair
    asked: OrderedDict[int, _Asked] = field(default_factory=OrderedDict)
    by_key: dict[Key, list[int]] = field(default_factory=dict)  # lists: most keys have one request
    by_robot: dict[str, OrderedDict[int, None]] = field(default_factory=dict)  # each robot's, oldest first
    moved: dict[Key, Key] = field(default_factory=dict)  # a robot's stamp -> the last stamp it was moved to
    served: dict[str, int] = field(default_factory=dict)  # replies routed to each robot (``fogiac status``)
    lost: dict[str, int] = field(default_factory=dict)  # of those, the ones its link was gone for (undelivered)
    seq: int = 0
    counts: dict[str, int] = field(default_factory=lambda: dict.fromkeys(
        ("forwarded", "answered", "undelivered", "restamped", "queued", "unmatched", "keyless", "expired",
         "forgotten"), 0))

    @property
    def restamps(self) -> bool:
        return self.pair.match == DEFAULT_MATCH

    def add(self, asked: _Asked) -> int:
        self.seq += 1
        self.asked[self.seq] = asked
        self.by_key.setdefault(asked.key, []).append(self.seq)
        self.by_robot.setdefault(asked.robot, OrderedDict())[self.seq] = None
        return self.seq

    def drop(self, seq: int) -> None:
        asked = self.asked.pop(seq)
        queue = self.by_key[asked.key]
        queue.remove(seq)
        if not queue:
            del self.by_key[asked.key]
        mine = self.by_robot[asked.robot]
        del mine[seq]
        if not mine:
            del self.by_robot[asked.robot]

    def free_stamp(self, own: Key, limit: int) -> Key:
        """A stamp no request in flight has, from ``own`` on. The search starts after the last stamp ``own`` was
        moved to, so a robot that sends one stamp over and over costs a step or two each, not the whole chain."""
        if own not in self.by_key:
            return own
        last = self.moved.get(own)
        key = _next_stamp(last if last is not None and last in self.by_key else own)  # a freed one: from own again
        while key in self.by_key:
            key = _next_stamp(key)
        if len(self.moved) >= limit:
            self.moved.clear()
        self.moved[own] = key
        return key


class ReplyRouter:
    """Which robot each reply of the fleet's shared nodes goes to (see the module docstring). Thread-safe."""

    def __init__(self, *, pending: int = PENDING, expire_s: float = EXPIRE_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.pending, self.expire_s, self._clock = pending, expire_s, clock
        self._lock = threading.Lock()
        self._nodes: dict[str, _Node] = {}  # by the shared node's name
        self._requests: dict[str, _Node] = {}  # by request topic
        self._replies: dict[str, _Node] = {}  # by reply topic

    def configure(self, pairs: Sequence[SharedPair]) -> None:
        """Follow the access file's shared nodes; a node whose pair is unchanged keeps its waiting requests."""
        with self._lock:
            nodes = {}
            for pair in pairs:
                if pair.match is None:
                    continue  # no key: its outputs go to every robot it serves
                old = self._nodes.get(pair.node)
                nodes[pair.node] = old if old is not None and old.pair == pair else _Node(pair)
            self._nodes = nodes
            self._requests = {t: n for n in nodes.values() for t in n.pair.requests}
            self._replies = {t: n for n in nodes.values() for t in n.pair.replies}

    def match_of(self, topic: str) -> str | None:
        """The key field of a routed request or reply topic; None: the topic is not routed."""
        node = self._requests.get(topic) or self._replies.get(topic)
        return node.pair.match if node is not None else None

    def routes(self, topic: str) -> bool:
        """Whether ``topic``'s messages are replies that go to one robot each."""
        return topic in self._replies

    def request(self, topic: str, robot: str, data: Payload, key_of: KeyOf | None) -> Payload | None:
        """What to hand the node for ``robot``'s request on ``topic`` (its stamp perhaps moved), remembered as
        waiting; ``data`` itself when the topic is not a routed request; None when it has no key (not sent)."""
        node = self._requests.get(topic)
        if node is None:
            return data
        key = key_of(data) if key_of is not None else None
        with self._lock:
            if key is None:
                node.counts["keyless"] += 1
                return None
            now = self._clock()
            self._expire(node, now)
            own = key
            if node.restamps:
                key = node.free_stamp(own, self.pending)
                if key != own:
                    data = _with_stamp(data, key)
                    node.counts["restamped"] += 1
            elif key in node.by_key:
                node.counts["queued"] += 1  # behind a request with the same key: answered after it
            node.add(_Asked(robot, key, own, now, node.pair.replies))
            mine = node.by_robot[robot]
            while len(mine) > self.pending:  # this robot's oldest: a robot that floods forgets only its own
                node.drop(next(iter(mine)))
                node.counts["forgotten"] += 1
            node.counts["forwarded"] += 1
        return data

    def reply(self, topic: str, data: Payload, key_of: KeyOf | None) -> tuple[str, Payload] | None:
        """The robot a reply on a routed ``topic`` goes to, and the reply as it sees it (its own stamp back);
        None: it answers no waiting request (dropped, counted)."""
        node = self._replies.get(topic)
        if node is None:
            raise KeyError(f"{topic} is not a routed reply topic")
        key = key_of(data) if key_of is not None else None
        with self._lock:
            self._expire(node, self._clock())
            queue = node.by_key.get(key) if key is not None else None
            seq = next((s for s in queue if topic in node.asked[s].waiting), None) if queue else None
            if seq is None:
                node.counts["unmatched"] += 1
                return None
            asked = node.asked[seq]
            asked.waiting = asked.waiting - {topic}
            if not asked.waiting:
                node.drop(seq)
            node.counts["answered"] += 1
            if len(node.served) < 4 * self.pending or asked.robot in node.served:  # robots come and go: bounded
                node.served[asked.robot] = node.served.get(asked.robot, 0) + 1
        return asked.robot, (_with_stamp(data, asked.own) if asked.own != asked.key else data)

    def undelivered(self, topic: str, robot: str | None = None) -> None:
        """Count a routed reply whose robot has no link that hears ``topic`` now (it went away, or was revoked)."""
        node = self._replies.get(topic)
        if node is not None:
            with self._lock:
                node.counts["undelivered"] += 1
                if robot is not None and (robot in node.lost or len(node.lost) < 4 * self.pending):
                    node.lost[robot] = node.lost.get(robot, 0) + 1

    def robot_figures(self, robot: str) -> dict[str, int] | None:
        """The replies routed to ``robot`` over every shared node (``served``) and, of those, the ones that found
        no link of it (``undelivered``): what its edge end hears of them (:mod:`.cloud`'s REPORT). None when no
        shared node is routed (one edge, or a fleet whose nodes serve robots of their own)."""
        with self._lock:
            if not self._nodes:
                return None
            return {"served": sum(n.served.get(robot, 0) for n in self._nodes.values()),
                    "undelivered": sum(n.lost.get(robot, 0) for n in self._nodes.values())}

    def _expire(self, node: _Node, now: float) -> None:
        while node.asked:
            seq, asked = next(iter(node.asked.items()))
            if now - asked.at <= self.expire_s:
                return
            node.drop(seq)
            node.counts["expired"] += 1

    def stats(self) -> dict[str, dict[str, Any]]:
        """Per shared node: requests forwarded and answered (and of those, undelivered: the robot had gone),
        replies unmatched, requests keyless, restamped (their stamp was in flight already), queued (their key was:
        answered in arrival order), expired or forgotten, how many wait now, the replies each robot got (``served``)
        and of those the ones its link was gone for (``lost``)."""
        with self._lock:
            return {name: {**node.counts, "pending": len(node.asked), "served": dict(sorted(node.served.items())),
                           "lost": dict(sorted(node.lost.items()))}
                    for name, node in sorted(self._nodes.items())}
