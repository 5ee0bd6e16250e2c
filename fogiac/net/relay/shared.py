"""The cloud end's local topics, shared by the sessions of every edge linked to it.

A ROS node may register a topic once as a publisher and once as a subscriber, and the cloud end is
one node however many edges are linked (one session per edge identity, :mod:`fogiac.net.relay.cloud`).
So each topic the edges ask for has one subscription here, fanned out to every session that asked
(each compresses and queues for its own link), and each topic the edges send has one publisher,
which every session that opened it publishes through. The first session to need a topic registers
it, the last to let go withdraws it: with one edge this is exactly the session's own registration.

A session that joins a latched topic after its first message gets the last one, as a late ROS
subscriber of a latched publisher would.

A fleet's sessions each belong to a robot (the identity in its certificate). The replies of a shared
request/reply node are not fanned out to every session: each goes only to the sessions of the robot whose
request it answers, as the :class:`~fogiac.net.relay.replyroute.ReplyRouter` remembers it from the
request's way in (and a routed reply topic's latched message is never replayed to a joining session: it
answered someone else). With no router, or no shared node in it (one edge), nothing changes.
"""

from __future__ import annotations

import logging
import threading
from typing import TYPE_CHECKING

from fogiac.net.relay.errors import RelayError
from fogiac.net.relay.framing import Payload
from fogiac.net.relay.match import KeyOf, key_reader
from fogiac.net.relay.pubsub import LocalPublisher, LocalSubscription, TopicMeta
from fogiac.net.relay.ratelog import RateLimitedLog
from fogiac.net.relay.replyroute import ReplyRouter

if TYPE_CHECKING:
    from fogiac.net.relay.node import RelayNode
    from fogiac.net.relay.session import _Sink, _Source

log = logging.getLogger(__name__)


class _Fan:
    """One topic sent to the edges: a single subscription, each message handed to every session's source."""

    def __init__(self, topics: SharedTopics, topic: str) -> None:
        self.topics, self.topic = topics, topic
        self.sources: list[_Source] = []
        self.robots: dict[_Source, str] = {}  # the robot each source's session belongs to
        self.meta: TopicMeta | None = None
        self.latched: bytes | None = None
        self.sub = LocalSubscription(topics.node, topic, on_meta=self._meta, on_message=self._message)

    def _meta(self, meta: TopicMeta) -> None:
        with self.topics.lock:
            self.meta = meta
            sources = list(self.sources)
        for source in sources:
            source._meta(meta)

    def _message(self, data: Payload) -> None:
        router = self.topics.router
        if router is not None and router.routes(self.topic):
            self._route(router, data)
            return
        with self.topics.lock:
            if self.meta is not None and self.meta.latching:
                self.latched = bytes(data)
            sources = list(self.sources)
        for source in sources:
            source._message(data)

    def _route(self, router: ReplyRouter, data: Payload) -> None:
        """A shared node's reply: to the sessions of the robot that asked, or to none."""
        routed = router.reply(self.topic, data, self.topics.reader(self.topic, self.meta))
        if routed is None:
            return
        robot, reply = routed
        with self.topics.lock:
            sources = [s for s in self.sources if self.robots.get(s) == robot]
        if not sources:
            router.undelivered(self.topic, robot)
        for source in sources:
            source._message(reply)


class _Feed:
    """A session's source fed by its topic's fan."""

    def __init__(self, topics: SharedTopics, source: _Source, robot: str) -> None:
        self.topics, self.source, self.robot = topics, source, robot

    def start(self) -> None:
        self.topics.attach_source(self.source, self.robot)

    def stop(self) -> None:
        self.topics.detach_source(self.source)


class _Merge:
    """One topic the edges send: a single publisher, counted by the sessions' sinks that use it."""

    def __init__(self, topics: SharedTopics, topic: str, meta: TopicMeta) -> None:
        self.topic, self.users = topic, 0
        self.pub = LocalPublisher(topics.node, topic, meta, depth=topics.depth)


class _Outlet:
    """A session's sink publishing through its topic's merge (a shared node's request: remembered as its
    robot's, see :class:`~fogiac.net.relay.replyroute.ReplyRouter`)."""

    def __init__(self, topics: SharedTopics, topic: str, meta: TopicMeta, robot: str) -> None:
        self.topics, self.topic, self.meta, self.robot = topics, topic, meta, robot
        self._merge: _Merge | None = None

    @property
    def drops(self) -> int:
        merge = self._merge
        return merge.pub.drops if merge is not None else 0

    def start(self) -> None:
        self._merge = self.topics.attach_sink(self.topic, self.meta)

    def stop(self) -> None:
        merge, self._merge = self._merge, None
        if merge is not None:
            self.topics.detach_sink(merge)

    def publish(self, data: Payload) -> None:
        merge = self._merge
        if merge is None:
            return
        router = self.topics.router
        if router is None or router.match_of(self.topic) is None:
            merge.pub.publish(data)
            return
        # Remembered and handed on in one step: the node hears the robots' requests in the order they are
        # remembered, which equal keys other than a stamp are answered in.
        with self.topics.ordered:
            routed = router.request(self.topic, self.robot, data, self.topics.reader(self.topic, self.meta))
            if routed is not None:
                merge.pub.publish(routed)


class SharedTopics:
    """The registrations of one cloud end's node, shared by its sessions (see the module docstring).

    :meth:`feed` and :meth:`outlet` are what a :class:`~fogiac.net.relay.session.Session` takes as its
    ``feed`` and ``outlet``."""

    def __init__(self, node: RelayNode, *, depth: int, router: ReplyRouter | None = None) -> None:
        self.node, self.depth, self.router = node, depth, router
        self.lock = threading.Lock()  # the fans' and merges' members: held briefly, messages take it too
        # One registration change at a time, start or stop included: a topic one session lets go of is
        # withdrawn from the master before another session's registers it again (the node holds one each).
        self._changing = threading.Lock()
        self._fans: dict[str, _Fan] = {}
        self._merges: dict[str, _Merge] = {}
        self.ordered = threading.Lock()  # a shared node's requests: remembered and published in one order
        self._readers: dict[tuple[str, TopicMeta | None], KeyOf | None] = {}
        self._quiet = RateLimitedLog(log)

    def feed(self, source: _Source, robot: str = "") -> _Feed:
        return _Feed(self, source, robot)

    def outlet(self, sink: _Sink, meta: TopicMeta, robot: str = "") -> _Outlet:
        return _Outlet(self, sink.topic, meta, robot)

    def reader(self, topic: str, meta: TopicMeta | None) -> KeyOf | None:
        """How a routed topic's messages of ``meta`` are keyed (its publisher's definition); None: they have no
        key (logged), so its requests are not sent and its replies reach no robot."""
        router = self.router
        match = router.match_of(topic) if router is not None else None
        if match is None:
            return None
        found = (match, meta)
        with self.lock:
            if found in self._readers:
                return self._readers[found]
        try:
            reader: KeyOf | None = key_reader(match, meta.type if meta is not None else "*",
                                              meta.definition if meta is not None else "")
        except RelayError as err:
            self._quiet.warning("key", "%s: %s; its messages have no key and reach no robot", topic, err)
            reader = None
        with self.lock:
            if len(self._readers) >= 256:  # one per type and definition seen: a hostile edge's OPENs stay bounded
                self._readers.clear()
            self._readers[found] = reader
        return reader

    def attach_source(self, source: _Source, robot: str = "") -> None:
        """Join (or make and start) the topic's subscription; RelayError, as a subscription's start, if the
        master refuses it."""
        with self._changing:
            self._attach_source(source, robot)

    def _attach_source(self, source: _Source, robot: str) -> None:
        routed = self.router is not None and self.router.routes(source.topic)
        with self.lock:
            fan = self._fans.get(source.topic)
            made = fan is None
            if fan is None:
                fan = self._fans[source.topic] = _Fan(self, source.topic)
            elif fan.meta is not None:  # known already: OPEN before the first DATA, and the latched message
                source._meta(fan.meta)
                if fan.latched is not None and not routed:  # a routed reply answered another request
                    source._message(fan.latched)
            fan.sources.append(source)
            fan.robots[source] = robot
        if made:
            try:
                fan.sub.start()
            except BaseException:
                with self.lock:
                    fan.sources.remove(source)
                    fan.robots.pop(source, None)
                    if self._fans.get(source.topic) is fan:
                        del self._fans[source.topic]
                raise

    def detach_source(self, source: _Source) -> None:
        with self._changing:
            self._detach_source(source)

    def _detach_source(self, source: _Source) -> None:
        with self.lock:
            fan = self._fans.get(source.topic)
            if fan is None or source not in fan.sources:
                return
            fan.sources.remove(source)
            fan.robots.pop(source, None)
            last = not fan.sources
            if last:
                del self._fans[source.topic]
        if last:
            fan.sub.stop()

    def attach_sink(self, topic: str, meta: TopicMeta) -> _Merge:
        """Join (or make and advertise) the topic's publisher; RelayError if the master refuses it."""
        with self._changing:
            return self._attach_sink(topic, meta)

    def _attach_sink(self, topic: str, meta: TopicMeta) -> _Merge:
        with self.lock:
            merge = self._merges.get(topic)
            made = merge is None
            if merge is None:
                merge = self._merges[topic] = _Merge(self, topic, meta)
            elif merge.pub.meta.md5sum != meta.md5sum:
                log.warning("two edges send %s, as %s and as %s: published as %s", topic, merge.pub.meta.type,
                            meta.type, merge.pub.meta.type)
            merge.users += 1
        if made:
            try:
                merge.pub.start()
            except BaseException:
                self._detach_sink(merge, stop=False)
                raise
        return merge

    def detach_sink(self, merge: _Merge) -> None:
        with self._changing:
            self._detach_sink(merge)

    def _detach_sink(self, merge: _Merge, *, stop: bool = True) -> None:
        with self.lock:
            merge.users -= 1
            last = merge.users <= 0
            if last and self._merges.get(merge.topic) is merge:
                del self._merges[merge.topic]
        if last and stop:
            merge.pub.stop()
