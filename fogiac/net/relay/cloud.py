"""The cloud end: accepts the edge's TLS connection and sources what the edge asks for.

Only a connection that completes mutual TLS and opens with a HELLO becomes the session; a
newer one replaces an older (the edge reconnected after a half-open link), and garbage on any
connection closes only that connection.
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
from fogiac.net.relay.graph import GraphState
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
            threading.Thread(target=self._serve, args=(raw, addr), name="relay-conn", daemon=True).start()

    def _serve(self, raw: socket.socket, addr: tuple[str, int]) -> None:
        peer = f"{addr[0]}:{addr[1]}"
        try:
            raw.settimeout(HANDSHAKE_TIMEOUT)
            sock = self._ctx.wrap_socket(raw, server_side=True)
        except (ssl.SSLError, OSError) as err:
            log.warning("refused TLS connection from %s: %s", peer, err)
            raw.close()
            return
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
            return
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
            session = Session(sock=sock, node=self.node, config=self.config, peer=f"edge {peer}")
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
            graph = self.local_graph()
            if graph is not None and graph != last:
                session.send(framing.json_frame(Kind.STATE, graph.to_json()))
                last = graph
            session.closed.wait(self.config.poll_interval)

    def _on_subscribe(self, session: Session, frame: Frame) -> None:
        body = framing.parse_json(frame)
        if not isinstance(body.get("topic"), str):
            raise FrameError("SUBSCRIBE needs a topic")
        session.start_source(body["topic"], str(body.get("compression", "none")))

    def _on_unsubscribe(self, session: Session, frame: Frame) -> None:
        body = framing.parse_json(frame)
        session.stop_source(str(body.get("topic", "")))
