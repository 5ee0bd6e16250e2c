"""The edge end: dials the cloud end, keeps the link up, and decides what crosses it.

The edge owns the topic policy. It polls its own master, hears the cloud's graph in STATE
frames, and applies :func:`~fogiac.net.relay.graph.select_routes`: an outgoing route makes
the edge a source; an incoming one becomes a SUBSCRIBE to the cloud. A lost link is redialled
with bounded exponential backoff, and the routes are rebuilt from scratch on the new one.
The cloud may open only topics the edge asked it for; whatever else it opens is refused.

A fleet's cloud end may refuse the edge itself (its robot revoked: a REFUSE frame with the reason instead of
the HELLO answer). Redialling at the normal pace would change nothing but the cloud end's log, so a refused
edge waits longer each time, from ``refused_backoff_initial`` (1 s) doubling to ``refused_backoff_max``
(30 s), says why in its log and in its stats (``link_refused``), and links again at its next dial once the
robot is restored: within 30 s and the cloud end's access poll. SIGHUP (``fogiac robot restore`` sends it to
the robot's edge ends on its machine) makes it dial at once instead.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import socket
import ssl
import threading

from fogiac.net.relay import framing
from fogiac.net.relay.cloud import HANDSHAKE_TIMEOUT, PROTOCOL_VERSION
from fogiac.net.relay.config import EdgeConfig
from fogiac.net.relay.end import RelayEnd
from fogiac.net.relay.errors import RelayError
from fogiac.net.relay.framing import Frame, FrameError, Kind
from fogiac.net.relay.graph import GraphState, Route, select_routes, type_hints
from fogiac.net.relay.session import Session, read_frame, send_now
from fogiac.net.relay.stats import RelayStats
from fogiac.net.relay.tls import client_context, expected_server_name

log = logging.getLogger(__name__)


class Refused(RelayError):
    """The cloud end refused this edge (a REFUSE frame): ``reason`` says why (``revoked``...)."""

    def __init__(self, reason: str) -> None:
        super().__init__(f"refused: {reason}")
        self.reason = reason


def refusal(frame: Frame) -> str:
    """The reason a REFUSE frame gives, made printable and short: the cloud end is trusted, its bytes are not."""
    reason = framing.parse_json(frame).get("reason")
    text = reason if isinstance(reason, str) else "no reason given"
    return "".join(c if c.isprintable() else "?" for c in text)[:120]


class EdgeRelay(RelayEnd):
    role = "edge"

    def __init__(self, config: EdgeConfig) -> None:
        super().__init__(config, config.caller_id)
        self.edge_config = config
        self._ctx = client_context(config.certs, config.client)
        self._server_name = expected_server_name(config.certs, config.server_name)
        self._wake = threading.Event()
        self._cloud_graph = GraphState()
        self.connected = threading.Event()
        self.last_error: str | None = None
        self._asked: set[str] = set()  # topics this link asked the cloud for (SUBSCRIBE)
        self.link_refused: str | None = None  # why the cloud end refused this edge at its last dial (None: it did not)
        self._hurry = threading.Event()  # set by stop() and redial_now(): the wait between dials ends at once

    def _start_link(self) -> None:
        self._spawn(self._dial_loop, "relay-dial")

    def _stop_link(self) -> None:
        self._wake.set()
        self._hurry.set()

    def redial_now(self) -> None:
        """Dial at once instead of at the end of the current wait (SIGHUP: the robot was restored)."""
        self._hurry.set()

    def _pause(self, delay: float) -> bool:
        """Wait ``delay`` before the next dial; True when :meth:`redial_now` cut it short."""
        hurried = self._hurry.wait(delay)
        self._hurry.clear()
        return hurried and not self._stopping.is_set()

    def _dial_loop(self) -> None:
        config = self.edge_config
        delay = config.backoff_initial
        while not self._stopping.is_set():
            try:
                sock = self._dial()
            except Refused as err:  # dialling faster changes nothing: wait longer each time, up to the cap
                self.last_error, self.link_refused = str(err), err.reason
                delay = min(max(delay * 2, config.refused_backoff_initial), config.refused_backoff_max)
                log.warning("the cloud relay at %s:%d refused this edge: %s; retrying in %.1f s",
                            *config.connect, err.reason, delay)
                if self._pause(delay):
                    delay = config.backoff_initial
                continue
            except Exception as err:  # whatever the far end did, this thread must keep dialling
                self.last_error = str(err)
                log.warning("cannot reach the cloud relay at %s:%d: %s; retrying in %.1f s",
                            *config.connect, err, delay)
                delay = config.backoff_initial if self._pause(delay) else min(delay * 2, config.backoff_max)
                continue
            delay = config.backoff_initial
            self.link_refused = None
            self._asked = set()
            session = self._session(sock)
            session.handlers[Kind.STATE] = self._on_state
            session.handlers[Kind.REFUSE] = functools.partial(self._on_refuse, session)
            self._cloud_graph = GraphState()
            self.session = session
            self.connected.set()
            log.info("connected to the cloud relay at %s:%d", *self.edge_config.connect)
            routing = self._spawn(self._route_loop, "relay-routes", session)
            session.run()
            self.connected.clear()
            self._wake.set()
            routing.join(timeout=10)
            if not self._stopping.is_set():
                self.reconnects += 1
                if self.link_refused is not None:  # refused on the link itself: the same wait as at a dial
                    delay = min(max(delay * 2, config.refused_backoff_initial), config.refused_backoff_max)
                    log.warning("the cloud relay at %s:%d refused this edge: %s; retrying in %.1f s",
                                *config.connect, self.link_refused, delay)
                if self._pause(delay):
                    delay = config.backoff_initial

    def _session(self, sock: ssl.SSLSocket) -> Session:
        """The link's session (a replica group's links feed and publish through the group)."""
        return Session(sock=sock, node=self.node, config=self.config, peer="cloud",  # type: ignore[arg-type]
                       accepts=self._asked.__contains__)

    def _dial(self) -> ssl.SSLSocket:
        host, port = self.edge_config.connect
        raw = socket.create_connection((host, port), timeout=HANDSHAKE_TIMEOUT)
        try:
            sock = self._ctx.wrap_socket(raw, server_hostname=self._server_name)
            send_now(sock, framing.json_frame(Kind.HELLO, {"role": "edge", "version": PROTOCOL_VERSION}))
            # Under TLS 1.3 a refused client certificate shows up here, on the first read.
            hello = read_frame(sock)
            if hello.kind is Kind.REFUSE:
                raise Refused(refusal(hello))
            if hello.kind is not Kind.HELLO or framing.parse_json(hello).get("role") != "cloud":
                raise FrameError(f"expected the cloud's HELLO, got {hello.kind.name}")
        except BaseException:
            raw.close()
            raise
        sock.settimeout(None)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        return sock

    def _on_refuse(self, session: Session, frame: Frame) -> None:
        """Refused after the HELLO (revoked the instant it linked): the link ends, and the next dial waits."""
        self.link_refused = refusal(frame)
        session.close(f"refused: {self.link_refused}")

    def stats(self) -> RelayStats:
        session = self.session
        return dataclasses.replace(super().stats(), link_refused=self.link_refused,
                                   routed=session.peer_replies if session is not None else None)

    def _on_state(self, frame: Frame) -> None:
        try:
            self._cloud_graph = GraphState.from_json(framing.parse_json(frame))
        except (ValueError, TypeError, AttributeError) as err:
            raise FrameError(f"bad STATE frame: {err}") from None
        self._wake.set()

    def _route_loop(self, session: Session) -> None:
        """Poll the local graph, reconcile routes, until the session ends."""
        current: frozenset[Route] = frozenset()
        while session.alive and not self._stopping.is_set():
            local = self.local_graph()
            if local is not None:
                wanted = select_routes(local, self._cloud_graph, self.edge_config.policy)
                self._apply(session, current, wanted)
                current = wanted
                self.node.hint_types(type_hints(self._cloud_graph, self.edge_config.policy,  # type: ignore[union-attr]
                                                routed=[r.topic for r in wanted if r.direction == "in"]))
            self._wake.wait(self.config.poll_interval)
            self._wake.clear()
        if self.node is not None:
            self.node.hint_types({})

    def _apply(self, session: Session, current: frozenset[Route], wanted: frozenset[Route]) -> None:
        for route in sorted(wanted - current):
            comp = self.edge_config.compression_for(route.topic)
            if route.direction == "out":
                session.start_source(route.topic, comp)
            else:
                self._asked.add(route.topic)
                session.send(framing.json_frame(Kind.SUBSCRIBE, {"topic": route.topic, "compression": comp}))
                log.info("asking the cloud for %s (%s)", route.topic, comp)
        for route in sorted(current - wanted):
            if route.direction == "out":
                session.stop_source(route.topic)
            else:
                self._asked.discard(route.topic)
                session.send(framing.json_frame(Kind.UNSUBSCRIBE, {"topic": route.topic}))
                log.info("no longer asking the cloud for %s", route.topic)
