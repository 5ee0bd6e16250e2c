"""A replicated node at the edge: one relay process, one link per replica, first reply wins.

The copies of one node (the plan's routes whose ``Route.replica.group`` is equal, each on a host of
its own) are served by one :class:`ReplicaGroup` on the robot's master: one ROS node holding one
:class:`~fogiac.net.relay.edge.EdgeRelay`-style link per replica. Each of the node's ``in`` topics
has one subscription here, and every request read from it goes to every live replica (hedge
``all``), or to the fastest replica first and to the others only if no reply came within
``hedge_delay_s`` (hedge ``delayed``: Dean and Barroso's hedged request). Each ``out`` topic has one
publisher here, and the robot gets the first reply to each request; a later copy of it is dropped.

A reply names its request by a key (:mod:`fogiac.net.relay.match`, ``header.stamp`` by default), read
with the reply topic's message definition as that replica's link sent it: one reader per link and topic,
made at each OPEN, so one replica's definition never decides how another's replies are keyed. A
definition is the replica's word, so it is checked: its type must be the one the manifest states for
the topic (``message_types``), or else the one the topic's publisher here already has, and a definition
the reader refuses (malformed, self-referential, nested too deep) refuses that link's replies on the
topic, with a logged line, while the other links go on. What is remembered is bounded: the last
``remember`` requests, and which replica answered each (:class:`fogiac.net.replicas.Merge`).

The decisions and the figures are :class:`fogiac.net.replicas.Merge`'s (the Zenoh edge uses it too).
Per replica, the group counts requests sent, answers, answers won, duplicates dropped, the latency
of each answer (from the request's arrival here), and the age of its last answer; a replica with a
request unanswered for ``silent_after`` seconds while it is linked is "silent", one without a link
"down". :meth:`ReplicaGroup.stats` is what the stats file holds (``fogiac status`` reads it); each
link also writes its own relay stats file, as a single edge relay does.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import os
import signal
import ssl
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fogiac.msgtypes import canonical_type
from fogiac.net.relay.config import EdgeConfig, default_ros_host, parse_hostport, policy_from_spec
from fogiac.net.relay.edge import EdgeRelay
from fogiac.net.relay.errors import RelayError
from fogiac.net.relay.framing import Payload
from fogiac.net.relay.match import DEFAULT_MATCH, BadDefinition, KeyOf, key_reader
from fogiac.net.relay.monitor import Monitor
from fogiac.net.relay.node import RelayNode
from fogiac.net.relay.pubsub import LocalPublisher, LocalSubscription, TopicMeta
from fogiac.net.relay.session import Session, _Source
from fogiac.net.replicas import HEDGES, Merge

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ReplicaTarget:
    """Where one replica's cloud end is, and where its link writes its relay stats."""

    index: int
    host: str
    connect: tuple[str, int]
    server_name: str | None = None
    stats_file: Path | None = None


@dataclass(frozen=True, kw_only=True)
class GroupConfig:
    edge: EdgeConfig  # the robot side's master, certificates, topic policy, compression; its connect is unused
    group: str
    replicas: tuple[ReplicaTarget, ...]
    match: str = DEFAULT_MATCH
    hedge: str = "all"
    hedge_delay_s: float = 0.0
    remember: int = 4096
    silent_after: float = 3.0
    stats_file: Path | None = None
    types: tuple[tuple[str, str], ...] = ()  # topic -> its message type as the manifest states it

    def __post_init__(self) -> None:
        if self.hedge not in HEDGES:
            raise RelayError(f"hedge {self.hedge!r}: expected one of {', '.join(HEDGES)}")
        if not self.replicas:
            raise RelayError(f"replica group {self.group!r} has no replica to link")
        if len({r.index for r in self.replicas}) != len(self.replicas):
            raise RelayError(f"replica group {self.group!r}: two replicas with one index")
        if self.hedge_delay_s < 0 or self.remember < 1:
            raise RelayError("hedge_delay_s must be >= 0 and remember >= 1")


class _Fan:
    """One ``in`` topic: a single subscription on the robot's master, fanned out to the links' sources."""

    def __init__(self, group: ReplicaGroup, topic: str) -> None:
        self.group, self.topic = group, topic
        self.sources: dict[int, _Source] = {}
        self.meta: TopicMeta | None = None
        self.sub: LocalSubscription | None = None
        self.key: KeyOf | None = None

    def attach(self, index: int, source: _Source) -> None:
        with self.group.lock:
            self.sources[index] = source
            meta, start = self.meta, self.sub is None
            if start:
                self.sub = LocalSubscription(self.group.node, self.topic, on_meta=self._meta,
                                             on_message=self._message)
        if meta is not None:
            source._meta(meta)
        if start:
            assert self.sub is not None
            self.sub.start()

    def detach(self, index: int, source: _Source) -> None:
        with self.group.lock:
            if self.sources.get(index) is source:
                del self.sources[index]
            sub = self.sub if not self.sources else None
            if sub is not None:
                self.sub = None
        if sub is not None:
            sub.stop()

    def _meta(self, meta: TopicMeta) -> None:
        with self.group.lock:  # the robot's own publisher: its definition keys the requests
            if self.meta is None or self.key is None:
                self.meta = meta
                try:
                    self.key = self.group.reader(self.topic, meta)
                except BadDefinition as err:
                    log.error("%s: %s; its requests have no key", self.topic, err)
            sources = list(self.sources.values())
        for source in sources:
            source._meta(meta)

    def _message(self, data: Payload) -> None:
        self.group.request(self, data)


class _Merge:
    """One ``out`` topic: a single publisher on the robot's master that every link's sink publishes through."""

    def __init__(self, group: ReplicaGroup, topic: str) -> None:
        self.group, self.topic = group, topic
        self.pub: LocalPublisher | None = None
        self.linked: set[int] = set()
        self.keys: dict[int, KeyOf | None] = {}  # link -> how its replies are keyed (None: they have no key)
        self.refused: set[int] = set()  # links whose replies on this topic are dropped (their type or definition)

    def attach(self, index: int, meta: TopicMeta) -> None:
        """A link opened the topic: its own reader, from its own definition, once the type checks."""
        group = self.group
        with group.lock:
            self.linked.add(index)
            self.keys.pop(index, None)
            self.refused.discard(index)
            problem = group.type_problem(self.topic, meta, self.pub.meta if self.pub is not None else None)
            if problem is None:
                try:
                    self.keys[index] = group.reader(self.topic, meta)
                except BadDefinition as err:
                    problem = f"its message definition of {meta.type}: {err}"
            if problem is not None:
                self.refused.add(index)
                log.error("replica %d of %s: %s: %s; its replies there are refused", index + 1,
                          group.config.group, self.topic, problem)
                return
            if self.pub is not None:
                return
            self.pub = LocalPublisher(group.node, self.topic, meta, depth=group.config.edge.queue_depth)
            pub = self.pub
        pub.start()

    def detach(self, index: int) -> None:
        with self.group.lock:
            self.linked.discard(index)
            self.keys.pop(index, None)
            self.refused.discard(index)
            pub = self.pub if not self.linked else None
            if pub is not None:
                self.pub = None
        if pub is not None:
            pub.stop()

    @property
    def drops(self) -> int:
        pub = self.pub
        return pub.drops if pub is not None else 0


class _Outlet:
    """A link's sink for a merged topic: what it publishes goes through the group's merge."""

    def __init__(self, merge: _Merge, index: int, meta: TopicMeta) -> None:
        self.merge, self.index, self.meta = merge, index, meta

    @property
    def drops(self) -> int:
        return self.merge.drops

    def start(self) -> None:
        self.merge.attach(self.index, self.meta)

    def stop(self) -> None:
        self.merge.detach(self.index)

    def publish(self, data: Payload) -> None:
        self.merge.group.reply(self.merge, self.index, data)


class _Feed:
    """A link's source for a fanned topic: fed by the group's one subscription."""

    def __init__(self, fan: _Fan, index: int, source: _Source) -> None:
        self.fan, self.index, self.source = fan, index, source

    def start(self) -> None:
        self.fan.attach(self.index, self.source)

    def stop(self) -> None:
        self.fan.detach(self.index, self.source)


class _Link(EdgeRelay):
    """One replica's link: an edge relay's dialling and routing, on the group's node."""

    role = "edge"

    def __init__(self, group: ReplicaGroup, target: ReplicaTarget) -> None:
        config = dataclasses.replace(group.config.edge, connect=target.connect, server_name=target.server_name,
                                     stats_file=target.stats_file)
        super().__init__(config)
        self.group, self.index = group, target.index

    def start(self) -> None:
        self.node = self.group.node
        self._start_link()
        self._spawn(self._stats_loop, "relay-stats")

    def stop(self) -> None:
        self._stopping.set()
        self._stop_link()
        session = self.session
        if session is not None:
            session.close("relay stopping")
            session.closed.wait(10)
        for thread in self._threads:
            thread.join(timeout=5)

    def _session(self, sock: ssl.SSLSocket) -> Session:
        group, index = self.group, self.index
        return Session(sock=sock, node=self.node, config=self.config,  # type: ignore[arg-type]
                       peer=f"replica {index + 1} of {group.config.group}",
                       accepts=self._asked.__contains__,
                       feed=lambda source: _Feed(group.fan(source.topic), index, source),
                       outlet=lambda sink, meta: _Outlet(group.merge(sink.topic), index, meta))

    @property
    def linked(self) -> bool:
        session = self.session
        return self.connected.is_set() and session is not None and session.alive


class ReplicaGroup:
    """The edge of one replicated node; ``start``/``stop`` like a relay end."""

    def __init__(self, config: GroupConfig) -> None:
        self.config = config
        edge = config.edge
        self.node = RelayNode(master_uri=edge.master_uri, caller_id=edge.caller_id, host=edge.ros_host)
        self.lock = threading.RLock()
        self._fans: dict[str, _Fan] = {}
        self._merges: dict[str, _Merge] = {}
        self.links = [_Link(self, t) for t in config.replicas]
        self.core = Merge([(t.index, t.host) for t in config.replicas], hedge=config.hedge,
                          hedge_delay_s=config.hedge_delay_s, remember=config.remember,
                          silent_after=config.silent_after)
        self._stopping = threading.Event()
        self._threads: list[threading.Thread] = []
        self._monitor: Monitor | None = None

    # --- lifecycle -------------------------------------------------------------------------
    def redial_now(self) -> None:
        """Every link whose cloud end refused it dials now (SIGHUP: the robot was restored)."""
        for link in self.links:
            link.redial_now()

    def start(self) -> None:
        self.node.start()
        try:
            # The monitor's topics keep the node registered: the links' master checks look for it.
            self._monitor = Monitor(self.node)
            self._monitor.start()
            for link in self.links:
                link.start()
        except BaseException:
            self.node.stop()
            raise
        for target, name in ((self._hedge_loop, "replica-hedge"), (self._stats_loop, "replica-stats")):
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)
        log.info("replica group %s: %d replicas, match %s, hedge %s", self.config.group, len(self.links),
                 self.config.match, self.config.hedge)

    def stop(self) -> None:
        self._stopping.set()
        with self.core.changed:
            self.core.changed.notify_all()
        for link in self.links:
            link.stop()
        if self._monitor is not None:
            self._monitor.stop()
        self.node.stop()
        for thread in self._threads:
            thread.join(timeout=5)

    def __enter__(self) -> ReplicaGroup:
        self.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.stop()

    # --- topics ----------------------------------------------------------------------------
    def fan(self, topic: str) -> _Fan:
        with self.lock:
            return self._fans.setdefault(topic, _Fan(self, topic))

    def merge(self, topic: str) -> _Merge:
        with self.lock:
            return self._merges.setdefault(topic, _Merge(self, topic))

    def reader(self, topic: str, meta: TopicMeta) -> KeyOf | None:
        """How messages of ``meta`` on ``topic`` are keyed; None: they have no key (answered in order, see
        :class:`~fogiac.net.replicas.Merge`). :class:`BadDefinition` for a definition not to be read."""
        try:
            return key_reader(self.config.match, meta.type, meta.definition)
        except BadDefinition:
            raise
        except RelayError as err:
            log.warning("%s: %s; its messages have no key: each replica's replies answer its requests in order",
                        topic, err)
            return None

    def type_problem(self, topic: str, meta: TopicMeta, current: TopicMeta | None) -> str | None:
        """Why a link's ``meta`` for an out topic is refused: not the type the manifest states, or not the
        one the topic's publisher here already has (whose subscribers expect it)."""
        stated = dict(self.config.types).get(topic)
        if stated is not None and canonical_type(meta.type) != canonical_type(stated):
            return f"it sends {meta.type[:100]!r}, but the manifest states {stated}"
        if current is not None and (current.md5sum, current.type) != (meta.md5sum, meta.type):
            return (f"it sends {meta.type[:100]!r} ({meta.md5sum[:32]!r}), the topic here is {current.type} "
                    f"({current.md5sum})")
        return None

    # --- requests and replies --------------------------------------------------------------
    def _live(self) -> list[int]:
        return [link.index for link in self.links if link.linked]

    def request(self, fan: _Fan, data: Payload) -> None:
        key = fan.key(data) if fan.key is not None else None
        with self.lock:
            live = [i for i in self._live() if i in fan.sources]
        targets = self.core.request(fan.topic, key, data, live, time.monotonic())
        self._send(fan, data, targets)

    def _send(self, fan: _Fan, data: Payload, targets: list[int]) -> None:
        with self.lock:
            sources = [fan.sources[i] for i in targets if i in fan.sources]
        for source in sources:
            source._message(data)

    def _hedge_loop(self) -> None:
        while not self._stopping.is_set():
            with self.core.changed:
                due, now = self.core.next_due(), time.monotonic()
                if due is None or due > now:
                    self.core.changed.wait(1.0 if due is None else due - now)
                    continue
            for topic, data, targets in self.core.due(now, self._live()):
                self._send(self.fan(topic), data, targets)

    def reply(self, merge: _Merge, index: int, data: Payload) -> None:
        """A replica's reply, keyed by its own link's reader: published if it answers a request sent to it that
        no reply on this topic answered yet."""
        with self.lock:
            if index in merge.refused:
                return
            reader = merge.keys.get(index)
        key = reader(data) if reader is not None else None
        if self.core.reply(merge.topic, index, key, time.monotonic()):
            pub = merge.pub
            if pub is not None:
                pub.publish(data)

    # --- figures ---------------------------------------------------------------------------
    def stats(self) -> dict[str, Any]:
        """What the group's stats file holds: :meth:`fogiac.net.replicas.Merge.stats` with the group's name."""
        return {"group": self.config.group, "match": self.config.match,
                **self.core.stats(set(self._live()), time.monotonic())}

    def _stats_loop(self) -> None:
        said: set[int] = set()
        while not self._stopping.wait(1.0):
            doc = self.stats()
            for r in doc["replicas"]:
                if r["health"] == "silent" and r["index"] not in said:
                    log.warning("replica %d of %s on %s stopped answering (%d requests, last answer %s s ago)",
                                r["index"] + 1, self.config.group, r["host"], r["sent"], r["last_answer_s"])
                    said.add(r["index"])
                elif r["health"] == "ok":
                    said.discard(r["index"])
            if self.config.stats_file is not None:
                try:
                    write_json(self.config.stats_file, doc)
                except OSError as err:
                    log.warning("cannot write %s: %s", self.config.stats_file, err)


def write_json(path: Path, doc: dict[str, Any]) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(doc, separators=(",", ":")))
    os.replace(tmp, path)


# --- the process: ``python -m fogiac.net.relay.replicas`` (started by the relay's edge_up) -------
def parse_replica(text: str) -> ReplicaTarget:
    """``INDEX,HOST,ADDRESS[:PORT][,SERVER_NAME[,STATS_FILE]]``."""
    parts = text.split(",")
    if len(parts) < 3 or not parts[0].isdigit() or not parts[1] or not parts[2]:
        raise RelayError(f"--replica {text!r}: expected INDEX,HOST,ADDRESS[:PORT][,SERVER_NAME[,STATS_FILE]]")
    return ReplicaTarget(int(parts[0]), parts[1], parse_hostport(parts[2]),
                         parts[3] if len(parts) > 3 and parts[3] else None,
                         Path(parts[4]) if len(parts) > 4 and parts[4] else None)


def parse_type(text: str) -> tuple[str, str]:
    """``TOPIC=TYPE``."""
    topic, _, name = text.partition("=")
    if not topic.startswith("/") or not name:
        raise RelayError(f"--type {text!r}: expected TOPIC=TYPE")
    return topic, name


def main(argv: Sequence[str] | None = None) -> int:
    from fogiac.net.relay.compression import parse_spec  # noqa: PLC0415 (the process's own imports)

    parser = argparse.ArgumentParser(prog="python -m fogiac.net.relay.replicas",
                                     description="The edge of a replicated node: fan out, first reply wins.")
    parser.add_argument("--group", required=True)
    parser.add_argument("--replica", action="append", required=True,
                        help="INDEX,HOST,ADDRESS[:PORT][,SERVER_NAME[,STATS_FILE]], one per replica")
    parser.add_argument("--master", default="http://127.0.0.1:11311/")
    parser.add_argument("--certs", type=Path, required=True)
    parser.add_argument("--client", default="client", help="this edge's pair under --certs (CLIENT.pem/.key)")
    parser.add_argument("--ros-host", default=None)
    parser.add_argument("--stats-file", type=Path, default=None)
    parser.add_argument("--queue-depth", type=int, default=4)
    parser.add_argument("--topics", default="auto")
    parser.add_argument("--out", default="")
    parser.add_argument("--in", dest="in_topics", default="")
    parser.add_argument("--compression", default="none")
    parser.add_argument("--name", default="/fogiac_relay_replicas")
    parser.add_argument("--match", default=DEFAULT_MATCH)
    parser.add_argument("--hedge", default="all", choices=HEDGES)
    parser.add_argument("--hedge-delay", type=float, default=0.0)
    parser.add_argument("--type", action="append", default=[], dest="types",
                        help="TOPIC=TYPE: the message type the manifest states for a topic (replies checked with it)")
    parser.add_argument("--verbose", "-v", action="store_true")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    try:
        default, per_topic = parse_spec(args.compression)
        edge = EdgeConfig(master_uri=args.master, certs=args.certs, ros_host=args.ros_host or default_ros_host(),
                          queue_depth=args.queue_depth, connect=("", 0),
                          policy=policy_from_spec(args.topics, out_topics=args.out, in_topics=args.in_topics),
                          compression=default, topic_compression=tuple(sorted(per_topic.items())),
                          client=args.client, caller_id=args.name)
        group = ReplicaGroup(GroupConfig(
            edge=edge, group=args.group, replicas=tuple(parse_replica(r) for r in args.replica),
            match=args.match, hedge=args.hedge, hedge_delay_s=args.hedge_delay, stats_file=args.stats_file,
            types=tuple(parse_type(t) for t in args.types)))
    except RelayError as err:
        print(f"error: {err}", flush=True)
        return 2
    done = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: done.set())
    signal.signal(signal.SIGHUP, lambda *_: group.redial_now())  # as the edge end's: a restored robot dials now
    group.start()
    try:
        done.wait()
    finally:
        group.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
