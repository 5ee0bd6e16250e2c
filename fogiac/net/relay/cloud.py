"""The cloud end: accepts the edge's TLS connection and sources what the edge asks for.

Only a connection that completes mutual TLS and opens with a HELLO becomes the session; a
newer one replaces an older (the edge reconnected after a half-open link), and garbage on any
connection closes only that connection. The edge may ask for (SUBSCRIBE) and send (OPEN) only
the topics this end's policy lets cross in that direction; anything else is refused and counted.
At most ``max_handshakes`` connections are in TLS/HELLO at once (each has a thread and a
deadline); a connection beyond that is closed as soon as it is accepted, so idle or slow
connections cannot pile up threads.
"""

from __future__ import annotations

import logging
import socket
import ssl
import threading

from fogiac.errors import RelayError
from fogiac.net.relay import framing
from fogiac.net.relay.config import CloudConfig
from fogiac.net.relay.end import RelayEnd
from fogiac.net.relay.framing import Frame, FrameError, Kind
from fogiac.net.relay.graph import Direction, GraphState, may_cross
from fogiac.net.relay.session import Session, read_frame, send_now
from fogiac.net.relay.tls import server_context

log = logging.getLogger(__name__)
PROTOCOL_VERSION = 1
HANDSHAKE_TIMEOUT = 10.0


class CloudRelay(RelayEnd):
    role = "cloud"

    def __init__(self, config: CloudConfig) -> None:
        super().__init__(config, config.caller_id)
        self.cloud_config = config
        self._ctx = server_context(config.certs)
        self._listener: socket.socket | None = None
        self._swap = threading.Lock()
        self._graph = GraphState()  # this master's graph as last reported to the edge
        self._handshakes = threading.BoundedSemaphore(config.max_handshakes)
        self.turned_away = 0  # connections closed because too many were handshaking

    @property
    def address(self) -> tuple[str, int]:
        """Where the cloud end listens (the real port when 0 was asked for)."""
        assert self._listener is not None
        host, port = self._listener.getsockname()[:2]
        return host, port

    def _start_link(self) -> None:
        try:
            self._listener = socket.create_server(self.cloud_config.listen, backlog=16, reuse_port=False)
        except OSError as err:
            host, port = self.cloud_config.listen
            raise RelayError(f"cannot listen on {host}:{port}: {err}") from None
        log.info("cloud relay listening on %s:%d", *self.address)
        self._spawn(self._accept_loop, "relay-accept")

    def _stop_link(self) -> None:
        if self._listener is not None:
            self._listener.close()

    def _accept_loop(self) -> None:
        assert self._listener is not None
        while not self._stopping.is_set():
            try:
                raw, addr = self._listener.accept()
            except OSError:
                return
            if not self._handshakes.acquire(blocking=False):
                self.turned_away += 1
                log.warning("turned away %s:%d: %d connections already handshaking", *addr[:2],
                            self.cloud_config.max_handshakes)
                raw.close()
                continue
            threading.Thread(target=self._serve, args=(raw, addr), name="relay-conn", daemon=True).start()

    def _serve(self, raw: socket.socket, addr: tuple[str, int]) -> None:
        try:
            sock = self._handshake(raw, f"{addr[0]}:{addr[1]}")
        finally:
            self._handshakes.release()
        if sock is not None:
            self._run_session(sock, f"{addr[0]}:{addr[1]}")

    def _handshake(self, raw: socket.socket, peer: str) -> ssl.SSLSocket | None:
        """TLS and HELLO, each read bounded by HANDSHAKE_TIMEOUT; None when the peer fails them."""
        try:
            raw.settimeout(HANDSHAKE_TIMEOUT)
            sock = self._ctx.wrap_socket(raw, server_side=True)
        except (ssl.SSLError, OSError) as err:
            log.warning("refused TLS connection from %s: %s", peer, err)
            raw.close()
            return None
        try:
            hello = read_frame(sock)
            if hello.kind is not Kind.HELLO or framing.parse_json(hello).get("role") != "edge":
                raise FrameError(f"expected the edge's HELLO, got {hello.kind.name}")
            if framing.parse_json(hello).get("version") != PROTOCOL_VERSION:
                raise FrameError(f"edge speaks relay protocol {framing.parse_json(hello).get('version')}, "
                                 f"this cloud end {PROTOCOL_VERSION}")
            send_now(sock, framing.json_frame(Kind.HELLO, {"role": "cloud", "version": PROTOCOL_VERSION}))
            sock.settimeout(None)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        except (FrameError, OSError) as err:
            log.warning("dropping connection from %s: %s", peer, err)
            sock.close()
            return None
        return sock

    def _run_session(self, sock: ssl.SSLSocket, peer: str) -> None:
        with self._swap:
            if self._stopping.is_set():
                sock.close()
                return
            old = self.session
            if old is not None and old.alive:
                old.close(f"replaced by a new edge connection from {peer}")
            if old is not None:
                old.closed.wait(10)
                self.reconnects += 1
            assert self.node is not None
            session = Session(sock=sock, node=self.node, config=self.config, peer=f"edge {peer}",
                              accepts=lambda topic: self._allowed(topic, "out"))
            session.handlers[Kind.SUBSCRIBE] = lambda f: self._on_subscribe(session, f)
            session.handlers[Kind.UNSUBSCRIBE] = lambda f: self._on_unsubscribe(session, f)
            self.session = session
        log.info("edge connected from %s", peer)
        threading.Thread(target=self._report_graph, args=(session,), name="relay-poll", daemon=True).start()
        session.run()
        log.info("edge %s disconnected", peer)

    def _report_graph(self, session: Session) -> None:
        """Tell the edge about this master's graph whenever it changes (it decides routes)."""
        last: GraphState | None = None
        while session.alive and not self._stopping.is_set():
            graph = self.local_graph(types=True)  # the edge tells its master the types (rostopic echo)
            if graph is not None and graph != last:
                self._graph = graph
                session.send(framing.json_frame(Kind.STATE, graph.to_json()))
                last = graph
            session.closed.wait(self.config.poll_interval)

    def _on_subscribe(self, session: Session, frame: Frame) -> None:
        body = framing.parse_json(frame)
        if not isinstance(body.get("topic"), str):
            raise FrameError("SUBSCRIBE needs a topic")
        if not self._allowed(body["topic"], "in"):
            session.refuse(f"SUBSCRIBE for {body['topic']!r}")
            return
        session.start_source(body["topic"], str(body.get("compression", "none")))

    def _allowed(self, topic: str, direction: Direction) -> bool:
        policy = self.cloud_config.policy
        if may_cross(topic, direction, policy, self._graph):
            return True
        fresh = self.local_graph() if policy.auto else None  # the graph may have moved since the last poll
        return fresh is not None and may_cross(topic, direction, policy, fresh)

    def _on_unsubscribe(self, session: Session, frame: Frame) -> None:
        body = framing.parse_json(frame)
        session.stop_source(str(body.get("topic", "")))
