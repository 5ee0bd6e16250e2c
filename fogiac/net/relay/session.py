"""One live link between the ends: frames in and out over the TLS socket, and the topics
crossing it. When the connection ends, every registration it made is withdrawn.

Threads: the caller of :meth:`Session.run` reads frames; one writer drains the
:class:`~fogiac.net.relay.queues.Outbox`; one pinger keeps the clock offset fresh and declares
a silent peer dead. Topic sources add publisher-reader threads (see ``pubsub``).

The peer is not trusted: any failure while handling its frames (a codec's own error, a
decompression bomb, a MemoryError) closes this link, and the end that owns it redials or waits
for the next one. An OPEN for a topic this end did not agree to is refused and counted in
:attr:`Session.refused`, never published.
"""

from __future__ import annotations

import itertools
import logging
import socket
import ssl
import threading
import time
from collections.abc import Callable
from typing import Any, Protocol

from fogiac.net.relay import framing
from fogiac.net.relay.compression import codec
from fogiac.net.relay.config import EndConfig
from fogiac.net.relay.errors import RelayError
from fogiac.net.relay.framing import Frame, FrameError, Kind, Payload
from fogiac.net.relay.node import RelayNode
from fogiac.net.relay.pubsub import LocalPublisher, LocalSubscription, TopicMeta
from fogiac.net.relay.queues import Item, Outbox
from fogiac.net.relay.stats import ClockSync, TopicCounters
from fogiac.net.relay.tcpros import Stream

log = logging.getLogger(__name__)
Handler = Callable[[Frame], None]
Gate = Callable[[str], bool]  # may the peer start sending this topic to us?


class Feed(Protocol):
    """Where a source's messages come from, or a sink's go: the topic's own subscription or publisher,
    or a replica group's shared one (:mod:`fogiac.net.relay.replicas`)."""

    def start(self) -> Any: ...

    def stop(self) -> None: ...


class Outlet(Feed, Protocol):
    @property
    def drops(self) -> int: ...

    def publish(self, data: Payload) -> None: ...


SourceFeed = Callable[["_Source"], Feed]  # given the source, what feeds it (instead of a LocalSubscription)
SinkOutlet = Callable[["_Sink", TopicMeta], Outlet]  # given the sink, where it publishes (instead of a LocalPublisher)
_COALESCE = 256 * 1024  # join smaller writes: one TLS record beats several


def read_frame(source: socket.socket | Stream) -> Frame:
    """The next frame; FrameError before reading a payload whose length is absurd.

    A bare socket is read without buffering (the HELLO exchange, before the session's
    buffered stream takes over)."""
    stream = source if isinstance(source, Stream) else Stream(source, buffer=0)
    kind, topic, size = framing.parse_header(bytes(stream.exact(framing.HEADER.size)))
    return Frame(kind, topic, stream.exact(size) if size else b"")


def send_now(sock: socket.socket, frame: Frame) -> None:
    """Write one frame before the session's writer exists (the HELLO exchange)."""
    sock.sendall(framing.encode(frame))


class _Source:
    """A local topic sent over the link: subscribe, stamp, compress, queue latest-wins."""

    def __init__(self, session: Session, topic: str, compression: str, feed: SourceFeed | None = None) -> None:
        self.session, self.topic, self.id = session, topic, next(session._ids)
        self._codec = codec(compression)
        self.counters = session.tally(topic, "out", compression)
        self._lock = threading.Lock()
        self._opened = False
        self.sub: Feed = feed(self) if feed is not None else \
            LocalSubscription(session.node, topic, on_meta=self._meta, on_message=self._message)

    def _meta(self, meta: TopicMeta) -> None:
        with self._lock:
            if not self._opened:
                body = {"topic": self.topic, "compression": self._codec.name, **meta.to_json()}
                self.session.send(framing.json_frame(Kind.OPEN, body, topic=self.id))
                self._opened = True

    def _message(self, data: Payload) -> None:
        stamp = time.time_ns()
        with self._lock:
            body = self._codec.compress(data)
        prefix = framing.data_prefix(self.id, stamp, len(body))
        dropped = self.session.send_data(self.id, (prefix, body), depth=self.session.config.queue_depth)
        self.counters.count(len(data))
        if dropped:
            self.counters.drop(dropped)

    def stop(self) -> None:
        self.sub.stop()
        self.session.outbox.discard(self.id)
        self.session.send(Frame(Kind.CLOSE, self.id, b""))


class _Sink:
    """A peer's topic published locally with the peer publisher's type, md5sum and latching."""

    def __init__(self, session: Session, topic: str, meta: TopicMeta, compression: str,
                 outlet: SinkOutlet | None = None) -> None:
        self.session, self.topic = session, topic
        self._codec = codec(compression)
        self.pub: Outlet = outlet(self, meta) if outlet is not None else \
            LocalPublisher(session.node, topic, meta, depth=session.config.queue_depth)
        self.counters = session.tally(topic, "in", compression)
        if self.counters.more_drops is not None:  # the publisher this one replaces: its drops stay counted
            self.counters.drops += self.counters.more_drops()
        self.counters.more_drops = self._drops

    def _drops(self) -> int:
        return self.pub.drops

    def retire(self) -> None:
        """Stop publishing; the drops so far stay in the topic's totals."""
        self.pub.stop()
        if self.counters.more_drops == self._drops:
            self.counters.drops += self.pub.drops
            self.counters.more_drops = None

    def deliver(self, stamp: int, body: memoryview) -> None:
        data = self._codec.decompress(body)
        latency = time.time_ns() - (stamp - self.session.clock.offset_ns)
        self.counters.count(len(data), latency)
        self.pub.publish(data)


class Session:
    def __init__(self, *, sock: ssl.SSLSocket, node: RelayNode, config: EndConfig, peer: str,
                 accepts: Gate, feed: SourceFeed | None = None, outlet: SinkOutlet | None = None) -> None:
        self.sock, self.node, self.config, self.peer = sock, node, config, peer
        self.accepts = accepts
        # Set by a replica group's links: their topics are fed from, and published through, the group's
        # one subscription and one publisher per topic (one ROS node carries several links).
        self._feed, self._outlet = feed, outlet
        self.refused = 0  # OPENs and requests for topics outside this end's policy
        self.outbox = Outbox()
        self.clock = ClockSync()
        self._ids = itertools.count(1)
        self._sources: dict[str, _Source] = {}
        self._sinks: dict[int, _Sink] = {}
        # Every topic's totals for the life of the link, whether or not it is relayed now: a topic
        # that stops and starts again (auto topics follow the graph) goes on counting, and status
        # still counts a request whose publisher has already gone.
        self._totals: dict[tuple[str, str], TopicCounters] = {}
        self._lock = threading.Lock()
        self._totals_lock = threading.Lock()  # apart from _lock: a source is made while _lock is held
        self._send_lock = threading.Lock()  # whoever writes to the socket holds it
        self._closing = threading.Event()
        self.closed = threading.Event()
        self._last_rx = time.monotonic()
        self._writing_since: float | None = None  # set while a write is in the kernel's hands
        # One-way latency of the topics this end sends, as the peer measured them where they arrive
        # (a REPORT each ping interval): so this end's stats show it for both directions.
        self.peer_latency: dict[str, tuple[float | None, float | None]] = {}
        # A fleet's cloud end adds to each REPORT the replies its shared nodes routed to this link's robot
        # (``report_replies``); the edge keeps the latest (``peer_replies``: served, undelivered) for its stats.
        self.report_replies: Callable[[], dict[str, int] | None] | None = None
        self.peer_replies: dict[str, int] | None = None
        self.handlers: dict[Kind, Handler] = {
            Kind.OPEN: self._on_open, Kind.CLOSE: self._on_close, Kind.DATA: self._on_data,
            Kind.PING: self._on_ping, Kind.PONG: self._on_pong, Kind.REPORT: self._on_report,
        }

    # --- public ----------------------------------------------------------------------------
    def send(self, frame: Frame) -> None:
        if not self.outbox.put_control((framing.encode(frame),)) and not self._closing.is_set():
            self.close("the peer does not read: control queue full")

    def start_source(self, topic: str, compression: str) -> None:
        with self._lock:
            if topic in self._sources or self._closing.is_set():
                return
            try:
                source = self._sources[topic] = _Source(self, topic, compression, self._feed)
            except RelayError as err:
                log.error("cannot relay %s: %s", topic, err)
                return
        try:
            source.sub.start()
        except RelayError as err:
            log.error("cannot subscribe to %s: %s", topic, err)
            with self._lock:
                self._sources.pop(topic, None)
            return
        log.info("relaying %s to %s (%s)", topic, self.peer, compression)

    def stop_source(self, topic: str) -> None:
        with self._lock:
            source = self._sources.pop(topic, None)
        if source is not None:
            source.stop()
            log.info("stopped relaying %s", topic)

    def tally(self, topic: str, direction: str, compression: str) -> TopicCounters:
        """The running totals of ``topic`` one way on this link (kept when the topic stops)."""
        with self._totals_lock:
            counters = self._totals.get((topic, direction))
            if counters is None:
                counters = self._totals[(topic, direction)] = TopicCounters(topic, direction, compression)
            counters.compression = compression
            return counters

    def counters(self) -> list[TopicCounters]:
        with self._totals_lock:
            return list(self._totals.values())

    @property
    def alive(self) -> bool:
        return not self._closing.is_set()

    def close(self, reason: str) -> None:
        if not self._closing.is_set():
            self._closing.set()
            log.info("closing link to %s: %s", self.peer, reason)
            self.outbox.close()
            try:
                socket.socket.shutdown(self.sock, socket.SHUT_RDWR)
            except OSError:
                pass

    def run(self) -> None:
        """Serve the link until it ends, then withdraw every registration it made."""
        threading.Thread(target=self._write_loop, name="relay-writer", daemon=True).start()
        threading.Thread(target=self._ping_loop, name="relay-pinger", daemon=True).start()
        stream = Stream(self.sock)
        try:
            while not self._closing.is_set():
                frame = read_frame(stream)
                self._last_rx = time.monotonic()
                handler = self.handlers.get(frame.kind)
                if handler is None:
                    raise FrameError(f"unexpected {frame.kind.name} frame from {self.peer}")
                handler(frame)
        except FrameError as err:
            log.warning("malformed frame from %s: %s; dropping this connection", self.peer, err)
            self.close(str(err))
        except (OSError, ConnectionError) as err:
            self.close(f"connection lost: {err}")
        except RelayError as err:
            log.error("link to %s failed: %s", self.peer, err)
            self.close(str(err))
        except Exception as err:  # a codec's own error, MemoryError...: only this link ends
            log.error("link to %s failed: %s: %s", self.peer, type(err).__name__, err)
            self.close(f"{type(err).__name__}: {err}")
        finally:
            self.close("done")
            stream.close()
            self._teardown()

    # --- internals -------------------------------------------------------------------------
    def _teardown(self) -> None:
        with self._lock:
            sources, self._sources = list(self._sources.values()), {}
            sinks, self._sinks = list(self._sinks.values()), {}
        for source in sources:
            source.sub.stop()
        for sink in sinks:
            sink.pub.stop()
        self.sock.close()
        self.closed.set()

    def send_data(self, topic: int, item: Item, *, depth: int) -> int:
        """Queue a DATA frame latest-wins; returns how many stale ones were dropped.

        When the link is idle and nothing is queued, the calling thread writes a small one at
        once: items leave the outbox only under the send lock, so order is kept. Big ones go
        through the writer thread so reading the next one overlaps encrypting this one."""
        small = sum(len(b) for b in item) <= _COALESCE  # big ones pipeline through the writer
        if small and self._send_lock.acquire(blocking=False):
            try:
                if self.outbox.empty() and not self._closing.is_set():
                    self._write([item])
                    return 0
            except OSError as err:
                self.close(f"write failed: {err}")
                return 0
            finally:
                self._send_lock.release()
        return self.outbox.put(topic, item, depth=depth)

    def _write(self, batch: list[Item]) -> None:
        bufs = [buf for item in batch for buf in item]
        self._writing_since = time.monotonic()
        try:
            if len(bufs) > 1 and sum(len(b) for b in bufs) <= _COALESCE:
                self.sock.sendall(b"".join(bufs))
            else:
                for buf in bufs:
                    self.sock.sendall(buf)
        finally:
            self._writing_since = None

    def _write_loop(self) -> None:
        try:
            while self.outbox.wait():
                with self._send_lock:
                    self._write(self.outbox.take_batch())
        except OSError as err:
            self.close(f"write failed: {err}")

    def _ping_loop(self) -> None:
        n = 0
        while not self._closing.is_set():
            self.send(framing.ping(time.time_ns()))
            if n >= 8:  # with each ping at the steady interval, what arrived here and how late
                self._report()
            n += 1
            self._closing.wait(0.05 if n < 8 else self.config.ping_interval)
            now = time.monotonic()
            if now - self._last_rx > self.config.dead_after:
                self.close(f"no frame for {self.config.dead_after:g} s")
            since = self._writing_since
            if since is not None and now - since > self.config.write_timeout:
                # shutdown() in close() makes the blocked sendall fail, so the writer ends too
                self.close(f"a write has not finished in {self.config.write_timeout:g} s: the peer does not read")

    def _report(self) -> None:
        with self._lock:
            sinks = [s.counters.snapshot() for s in self._sinks.values()]
        latency = {t.topic: [t.latency_ms, t.latency_p99_ms] for t in sinks if t.latency_ms is not None}
        replies = self.report_replies() if self.report_replies is not None else None
        if latency or replies:  # "latency" always there: an edge from before "replies" requires it
            body: dict[str, Any] = {"latency": latency, **({"replies": replies} if replies else {})}
            self.send(framing.json_frame(Kind.REPORT, body))

    def _on_report(self, frame: Frame) -> None:
        report = framing.parse_json(frame)
        body = report.get("latency")
        if not isinstance(body, dict):
            raise FrameError("REPORT frame without a latency object")
        replies = report.get("replies")
        if isinstance(replies, dict):  # counts only: anything else in it is not kept
            self.peer_replies = {k: v for k in ("served", "undelivered")
                                 if isinstance(v := replies.get(k), int) and not isinstance(v, bool) and v >= 0}
        with self._lock:
            sources = set(self._sources)
        for topic, pair in body.items():
            if topic in sources and isinstance(pair, list) and len(pair) == 2 and \
                    all(v is None or isinstance(v, (int, float)) for v in pair):
                self.peer_latency[topic] = (pair[0], pair[1])  # only topics this end sends: no stray keys

    def _on_ping(self, frame: Frame) -> None:
        self.send(framing.pong(framing.parse_ping(frame), time.time_ns()))

    def _on_pong(self, frame: Frame) -> None:
        t0, peer = framing.parse_pong(frame)
        self.clock.add(t0, peer, time.time_ns())

    def _on_open(self, frame: Frame) -> None:
        body = framing.parse_json(frame)
        topic = str(body.get("topic"))
        if not self.accepts(topic):
            self.refuse(f"OPEN for {topic!r}")
            return
        try:
            meta = TopicMeta.from_json(body)
            compression = str(body.get("compression", "none"))
            sink = _Sink(self, topic, meta, compression, self._outlet)
        except (KeyError, ValueError, RelayError) as err:
            raise FrameError(f"bad OPEN frame: {err}") from None
        with self._lock:
            stale = [i for i, s in self._sinks.items() if s.topic == topic]
            old = [self._sinks.pop(i) for i in stale]
        for s in old:
            s.retire()
        try:
            sink.pub.start()
        except RelayError as err:
            log.error("cannot advertise %s: %s", topic, err)
            return
        with self._lock:
            self._sinks[frame.topic] = sink
        log.info("publishing %s (%s%s) from %s", topic, meta.type, ", latched" if meta.latching else "", self.peer)

    def refuse(self, what: str) -> None:
        """Count and log a request outside this end's topic policy; the link stays up."""
        self.refused += 1
        log.warning("refused %s from %s: not a topic this end relays in that direction", what, self.peer)

    def _on_close(self, frame: Frame) -> None:
        with self._lock:
            sink = self._sinks.pop(frame.topic, None)
        if sink is not None:
            sink.retire()
            log.info("peer stopped sending %s", sink.topic)

    def _on_data(self, frame: Frame) -> None:
        stamp, body = framing.split_data(frame.payload)
        sink = self._sinks.get(frame.topic)
        if sink is not None:  # DATA racing its CLOSE is harmless
            sink.deliver(stamp, body)
