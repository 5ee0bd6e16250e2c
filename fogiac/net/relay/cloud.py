"""The cloud end: accepts the edges' TLS connections and sources what each edge asks for.

Only a connection that completes mutual TLS and opens with a HELLO becomes a session. Each edge is
known by its client certificate (its common name, else its first subjectAltName: :func:`peer_identity`),
and the cloud end keeps one session per identity: edges of different identities are linked at once,
each with its own topics and queues (their local registrations are shared: :mod:`.shared`), while a
newer session of one identity replaces its older one (that edge reconnected after a half-open link).
Garbage on any connection closes only that connection. The edge may ask for (SUBSCRIBE) and send (OPEN) only
the topics this end's policy lets cross in that direction; anything else is refused and counted.
At most ``max_handshakes`` connections are in TLS/HELLO at once, ``max_per_source`` of them from
one address (each has a thread and a deadline: ``tls_timeout`` to send a first byte and finish
TLS, then ``HANDSHAKE_TIMEOUT`` for the HELLO). When a new connection finds no slot, the oldest
connection that has not sent a byte yet (of its own source first) is closed for it; if every slot
is talking TLS, the new one is closed. So idle connections cannot pile up threads, and they never
keep the edge out, even from the edge's own address: the edge speaks at once and is not evicted.
Refusals are logged at most once per kind per 10 s (:mod:`.ratelog`).

A fleet's cloud end also follows its access file (:mod:`.fleet`, ``fleet.json`` beside its certificates):
only a listed, unrevoked robot is linked, and only for its own namespace and the shared nodes' topics;
when the file changes, the links that lost their access are closed (within the watch's poll). A refused robot's
edge is told why (a REFUSE frame with the reason, ``revoked``, instead of the HELLO answer) so that it backs off
instead of redialling at its normal pace. The replies of
the shared request/reply nodes the file names go back only to the robot whose request each answers
(:mod:`.replyroute`; :meth:`CloudRelay.reply_stats` counts them, in the stats file too, and each robot's edge
end hears its own served and undelivered counts in the REPORT frames); with one edge nothing is routed. A
per-robot node's instances' topics (``/arm1/scan``) cross for their own robot as the file says, beyond the
topic policy, which names no robot so that robots come and go without this end restarted.
"""

from __future__ import annotations

import dataclasses
import logging
import socket
import ssl
import threading
from dataclasses import dataclass, field
from typing import Any

from fogiac.net.relay import framing
from fogiac.net.relay.config import CloudConfig
from fogiac.net.relay.end import RelayEnd
from fogiac.net.relay.errors import RelayError
from fogiac.net.relay.fleet import ACCESS_FILE, AccessWatch, FleetAccess
from fogiac.net.relay.framing import Frame, FrameError, Kind
from fogiac.net.relay.graph import Direction, GraphState, may_cross
from fogiac.net.relay.ratelog import RateLimitedLog
from fogiac.net.relay.replyroute import ReplyRouter
from fogiac.net.relay.session import Session, read_frame, send_now
from fogiac.net.relay.shared import SharedTopics
from fogiac.net.relay.stats import RelayStats
from fogiac.net.relay.tls import server_context

log = logging.getLogger(__name__)
PROTOCOL_VERSION = 1
HANDSHAKE_TIMEOUT = 10.0
REVOKED = "revoked"  # a REFUSE frame's reasons: the robot is revoked (``fogiac robot revoke``) ...
NOT_A_ROBOT = "not a robot of this fleet"  # ... or its certificate names no robot of the access file


def peer_identity(sock: ssl.SSLSocket) -> str:
    """The edge's identity: its certificate's common name, else its first subjectAltName (mutual TLS has
    verified the certificate against the stack's CA by now)."""
    cert: dict[str, Any] = dict(sock.getpeercert() or {})
    for rdn in cert.get("subject", ()):
        for key, value in rdn:
            if key == "commonName" and value:
                return str(value)
    for _, value in cert.get("subjectAltName", ()):
        return str(value)
    return "?"


@dataclass(eq=False)
class _Pending:
    """A connection in its handshake: evictable while it has not sent a byte (``silent``)."""

    raw: socket.socket
    source: str
    silent: bool = field(default=True)


class CloudRelay(RelayEnd):
    role = "cloud"

    def __init__(self, config: CloudConfig) -> None:
        super().__init__(config, config.caller_id)
        self.cloud_config = config
        self._ctx = server_context(config.certs)
        self._listener: socket.socket | None = None
        self._swap = threading.Lock()
        self.sessions: dict[str, Session] = {}  # edge identity -> its latest session (alive or ended)
        self._topics: SharedTopics | None = None
        self._graph = GraphState()  # this master's graph as last reported to the edge
        self._pending: list[_Pending] = []  # oldest first
        self._slots = threading.Lock()
        self._quiet = RateLimitedLog(log)
        self.turned_away = 0  # connections closed because too many were handshaking (new ones or idle ones)
        self.refused_links = 0  # fleet: linked TLS connections of an unknown or revoked robot, closed
        self.access: AccessWatch | None = None
        self.replies = ReplyRouter(pending=config.reply_pending, expire_s=config.reply_expire_s)

    @property
    def address(self) -> tuple[str, int]:
        """Where the cloud end listens (the real port when 0 was asked for)."""
        assert self._listener is not None
        host, port = self._listener.getsockname()[:2]
        return host, port

    def _start_link(self) -> None:
        assert self.node is not None
        self._topics = SharedTopics(self.node, depth=self.config.queue_depth, router=self.replies)
        self.access = AccessWatch(self.cloud_config.access_file or self.cloud_config.certs / ACCESS_FILE,
                                  self._access_changed)
        try:
            self._listener = socket.create_server(self.cloud_config.listen, backlog=16, reuse_port=False)
        except OSError as err:
            host, port = self.cloud_config.listen
            raise RelayError(f"cannot listen on {host}:{port}: {err}") from None
        log.info("cloud relay listening on %s:%d", *self.address)
        self._spawn(self._accept_loop, "relay-accept")
        self._spawn(self.access.run, "relay-access", self._stopping)

    def _stop_link(self) -> None:
        if self._listener is not None:
            try:  # close() alone does not wake a thread blocked in accept(): stop() waited out its 5 s join
                self._listener.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            self._listener.close()

    def _accept_loop(self) -> None:
        assert self._listener is not None
        while not self._stopping.is_set():
            try:
                raw, addr = self._listener.accept()
            except OSError:
                return
            pending = self._admit(raw, str(addr[0]))
            if pending is None:
                self.turned_away += 1
                self._quiet.warning("full", "turned away %s:%d: %d connections already in TLS", *addr[:2],
                                    self.cloud_config.max_handshakes)
                raw.close()
                continue
            threading.Thread(target=self._serve, args=(pending, addr), name="relay-conn", daemon=True).start()

    def _admit(self, raw: socket.socket, source: str) -> _Pending | None:
        """A slot for ``raw``, made by evicting the oldest silent connection if need be; None if none."""
        config = self.cloud_config
        with self._slots:
            mine = [p for p in self._pending if p.source == source]
            victim: _Pending | None = None
            if len(mine) >= config.max_per_source:
                victim = next((p for p in mine if p.silent), None)
                if victim is None:
                    return None
            elif len(self._pending) >= config.max_handshakes:
                victim = next((p for p in mine if p.silent), None) or next(
                    (p for p in self._pending if p.silent), None)
                if victim is None:
                    return None
            if victim is not None:
                self._pending.remove(victim)
            pending = _Pending(raw, source)
            self._pending.append(pending)
        if victim is not None:
            self.turned_away += 1
            self._quiet.warning("evicted", "closed an idle connection from %s for a new one", victim.source)
            try:
                victim.raw.shutdown(socket.SHUT_RDWR)  # its thread's read ends now; the thread closes it
            except OSError:
                pass
        return pending

    def _release(self, pending: _Pending) -> None:
        with self._slots:
            if pending in self._pending:
                self._pending.remove(pending)

    def _serve(self, pending: _Pending, addr: tuple[str, int]) -> None:
        try:
            sock = self._handshake(pending, f"{addr[0]}:{addr[1]}")
        finally:
            self._release(pending)
        if sock is not None:
            self._run_session(sock, f"{addr[0]}:{addr[1]}")

    def _handshake(self, pending: _Pending, peer: str) -> ssl.SSLSocket | None:
        """A first byte and TLS within ``tls_timeout``, then HELLO within HANDSHAKE_TIMEOUT; None when the
        peer fails them (or was evicted while silent)."""
        raw = pending.raw
        try:
            raw.settimeout(self.cloud_config.tls_timeout)
            if not raw.recv(1, socket.MSG_PEEK):
                raise OSError("closed before TLS")
            with self._slots:
                pending.silent = False  # talking TLS now: no longer evicted for a newer connection
            sock = self._ctx.wrap_socket(raw, server_side=True)
        except (ssl.SSLError, OSError) as err:
            self._quiet.warning("tls", "refused TLS connection from %s: %s", peer, err)
            raw.close()
            return None
        sock.settimeout(HANDSHAKE_TIMEOUT)
        try:
            hello = read_frame(sock)
            if hello.kind is not Kind.HELLO or framing.parse_json(hello).get("role") != "edge":
                raise FrameError(f"expected the edge's HELLO, got {hello.kind.name}")
            if framing.parse_json(hello).get("version") != PROTOCOL_VERSION:
                raise FrameError(f"edge speaks relay protocol {framing.parse_json(hello).get('version')}, "
                                 f"this cloud end {PROTOCOL_VERSION}")
            if (reason := self._refusal(identity := peer_identity(sock))) is not None:
                self._refuse(sock, identity, peer, reason)  # refused before the HELLO answer: a revoked robot's
                return None  # edge never counts itself linked, not even for a moment
            send_now(sock, framing.json_frame(Kind.HELLO, {"role": "cloud", "version": PROTOCOL_VERSION}))
            sock.settimeout(None)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        except (FrameError, OSError) as err:
            self._quiet.warning("hello", "dropping connection from %s: %s", peer, err)
            sock.close()
            return None
        return sock

    def _sessions(self) -> list[Session]:
        with self._swap:
            return list(self.sessions.values())

    def _run_session(self, sock: ssl.SSLSocket, peer: str) -> None:
        identity = peer_identity(sock)
        with self._swap:
            if self._stopping.is_set():
                sock.close()
                return
            if (reason := self._refusal(identity)) is not None:  # revoked between its HELLO and here
                self._refuse(sock, identity, peer, reason)
                return
            old = self.sessions.get(identity)  # the same edge's earlier session; other edges' stay
            if old is not None and old.alive:
                old.close(f"replaced by a new connection of edge {identity} from {peer}")
            if old is not None:
                old.closed.wait(10)
                self.reconnects += 1
            assert self.node is not None and self._topics is not None
            topics = self._topics
            session = Session(sock=sock, node=self.node, config=self.config, peer=f"edge {peer}",
                              accepts=lambda topic: self._allowed(topic, "out", identity),
                              feed=lambda source: topics.feed(source, identity),
                              outlet=lambda sink, meta: topics.outlet(sink, meta, identity))
            session.handlers[Kind.SUBSCRIBE] = lambda f: self._on_subscribe(session, f, identity)
            session.handlers[Kind.UNSUBSCRIBE] = lambda f: self._on_unsubscribe(session, f)
            session.report_replies = lambda: self.replies.robot_figures(identity)  # its edge shows them (status)
            self.sessions[identity] = self.session = session
        log.info("edge %s connected from %s", identity, peer)
        threading.Thread(target=self._report_graph, args=(session, identity), name="relay-poll", daemon=True).start()
        session.run()
        log.info("edge %s (%s) disconnected", identity, peer)

    def reload_access(self) -> None:
        """Read the fleet's access file now (SIGHUP) instead of at the next poll."""
        if self.access is not None:
            self.access.reload()

    def _rules(self) -> FleetAccess | None:
        return self.access.rules if self.access is not None else None

    def _refusal(self, identity: str) -> str | None:
        """Why the access file refuses this identity (``revoked``, or ``not a robot of this fleet``); None: linked."""
        rules = self._rules()
        if rules is None or rules.robot(identity) is not None:
            return None
        robot = rules.robots.get(identity)
        return REVOKED if robot is not None and robot.name in rules.revoked else NOT_A_ROBOT

    def _refuse(self, sock: ssl.SSLSocket, identity: str, peer: str, reason: str) -> None:
        """Tell the edge why in a REFUSE frame, then close: it backs off (:mod:`.edge`) instead of redialling at
        its normal pace. The frame goes to an edge that completed mutual TLS with the stack's CA only."""
        self.refused_links += 1
        self._quiet.warning("robot", "refused edge %s from %s: %s", identity, peer, reason)
        try:
            send_now(sock, framing.json_frame(Kind.REFUSE, {"reason": reason}))
        except OSError:
            pass  # gone already: nothing to tell
        sock.close()

    def reply_stats(self) -> dict[str, dict[str, Any]]:
        """Per shared request/reply node: requests forwarded, answered, waiting; replies that reached no robot;
        the replies each robot got (``served``) and of those the ones its link was gone for (``lost``), by robot
        name where the access file names it."""
        figures = self.replies.stats()
        rules = self._rules()
        if rules is not None:
            for node in figures.values():
                for key in ("served", "lost"):
                    node[key] = {(r.name if (r := rules.robots.get(i)) is not None else i): n
                                 for i, n in node[key].items()}
        return figures

    def stats(self) -> RelayStats:
        """The end's figures, and a fleet's reply routing (written to the stats file every second)."""
        return dataclasses.replace(super().stats(), replies=self.reply_stats() or None)

    def _access_changed(self, rules: FleetAccess | None) -> None:
        """Route the shared nodes' replies the file names; close the links of robots that lost their access
        (revoked, or dropped from the fleet)."""
        self.replies.configure(rules.shared if rules is not None else ())
        if rules is None:
            return
        with self._swap:
            gone = [(i, s) for i, s in self.sessions.items() if s.alive and rules.robot(i) is None]
        for identity, session in gone:
            session.close(f"edge {identity} is no longer a robot of this fleet (revoked or removed)")

    def _report_graph(self, session: Session, identity: str) -> None:
        """Tell the edge about this master's graph whenever it changes (it decides routes); a fleet's robot
        hears only of the topics it may use."""
        last: GraphState | None = None
        while session.alive and not self._stopping.is_set():
            graph = self.local_graph(types=True)  # the edge tells its master the types (rostopic echo)
            if graph is not None:
                self._graph = graph
                rules = self._rules()
                if rules is not None:
                    graph = rules.visible(identity, graph)
            if graph is not None and graph != last:
                session.send(framing.json_frame(Kind.STATE, graph.to_json()))
                last = graph
            session.closed.wait(self.config.poll_interval)

    def _on_subscribe(self, session: Session, frame: Frame, identity: str) -> None:
        body = framing.parse_json(frame)
        if not isinstance(body.get("topic"), str):
            raise FrameError("SUBSCRIBE needs a topic")
        if not self._allowed(body["topic"], "in", identity):
            session.refuse(f"SUBSCRIBE for {body['topic']!r}")
            return
        session.start_source(body["topic"], str(body.get("compression", "none")))

    def _allowed(self, topic: str, direction: Direction, identity: str) -> bool:
        rules = self._rules()
        if rules is not None and not rules.allows(identity, topic, direction):
            return False  # another robot's topic, a shared node's the wrong way, or a revoked robot's last frames
        if rules is not None and rules.crosses(identity, topic, direction):
            return True  # its own per-robot instance's topic: the access file names these, not the policy
        policy = self.cloud_config.policy
        if may_cross(topic, direction, policy, self._graph):
            return True
        fresh = self.local_graph() if policy.auto else None  # the graph may have moved since the last poll
        return fresh is not None and may_cross(topic, direction, policy, fresh)

    def _on_unsubscribe(self, session: Session, frame: Frame) -> None:
        body = framing.parse_json(frame)
        session.stop_source(str(body.get("topic", "")))
