"""One topic's local side: a publisher serving TCPROS subscribers, or a subscription that
pulls raw bytes from every publisher of the topic. Bytes in, bytes out; nothing is decoded.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from fogiac.net.relay import tcpros
from fogiac.net.relay.errors import RelayError
from fogiac.net.relay.framing import Payload
from fogiac.net.relay.rosapi import request_topic

if TYPE_CHECKING:
    from fogiac.net.relay.node import RelayNode

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TopicMeta:
    """What a far-side subscriber must see to accept the relay as the topic's publisher."""

    type: str
    md5sum: str
    definition: str
    latching: bool

    def to_json(self) -> dict[str, Any]:
        return {"type": self.type, "md5sum": self.md5sum, "definition": self.definition, "latching": self.latching}

    @classmethod
    def from_json(cls, body: dict[str, Any]) -> TopicMeta:
        return cls(str(body["type"]), str(body["md5sum"]), str(body.get("definition", "")), bool(body["latching"]))

    @classmethod
    def from_header(cls, header: dict[str, str]) -> TopicMeta:
        return cls(header.get("type", "*"), header.get("md5sum", "*"), header.get("message_definition", ""),
                   header.get("latching", "0") == "1")


class _Outlet:
    """One subscriber connection with its own bounded queue, so a slow reader lags alone.

    When the connection is idle the publishing thread writes the message itself, without
    blocking (``MSG_DONTWAIT``); whatever the kernel did not take, and anything that arrives
    meanwhile, goes to this outlet's thread. A thread handoff per message costs more latency
    than the copy on a busy machine.
    """

    def __init__(self, sock: socket.socket, depth: int, on_close: Callable[[_Outlet], None],
                 on_drop: Callable[[], None]) -> None:
        self.sock, self._depth, self._on_close, self._on_drop = sock, depth, on_close, on_drop
        self._queue: deque[Payload] = deque()
        self._rest: list[Payload] = []  # unsent tail of a message already started
        self._busy = False  # someone is writing to the socket right now
        self._cond = threading.Condition()
        self._closed = False
        threading.Thread(target=self._run, name="relay-outlet", daemon=True).start()

    def put(self, data: Payload) -> None:
        with self._cond:
            if self._closed:
                return
            if self._busy or self._queue or self._rest:
                while len(self._queue) >= self._depth:
                    self._queue.popleft()
                    self._on_drop()
                self._queue.append(data)
                self._cond.notify()
                return
            self._busy = True
        parts = [len(data).to_bytes(4, "little"), data]
        try:
            sent = self.sock.sendmsg(parts, [], socket.MSG_DONTWAIT)
        except BlockingIOError:
            sent = 0
        except OSError:
            self.close()
            return
        with self._cond:
            if sent < 4:
                self._rest = [parts[0][sent:], data]
            elif sent < 4 + len(data):
                self._rest = [memoryview(data)[sent - 4 :]]
            self._busy = False
            if self._rest or self._queue:  # wake the outlet's thread only when it has work:
                self._cond.notify()  # a wake-up per message cost more than the write itself

    def _run(self) -> None:
        try:
            while True:
                with self._cond:
                    while not self._closed and (self._busy or not (self._queue or self._rest)):
                        self._cond.wait()
                    if self._closed:
                        return
                    rest, self._rest = self._rest, []
                    batch = list(self._queue)
                    self._queue.clear()
                    self._busy = True
                for piece in rest:
                    self.sock.sendall(piece)
                if len(batch) > 1 and sum(map(len, batch)) < 256 * 1024:
                    self.sock.sendall(b"".join(tcpros.frame_message(d) for d in batch))
                else:
                    for data in batch:
                        tcpros.write_message(self.sock, data)
                with self._cond:
                    self._busy = False
        except OSError as err:
            log.debug("subscriber connection closed: %s", err)
        finally:
            self.close()
            self._on_close(self)

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify()
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self.sock.close()


_EARLY_WINDOW_S = 3.0  # how long known subscribers have to connect after the relay advertises


class LocalPublisher:
    """The relay advertising ``topic`` on its master with the source's type, md5 and latching."""

    def __init__(self, node: RelayNode, topic: str, meta: TopicMeta, *, depth: int) -> None:
        self.node, self.topic, self.meta, self._depth = node, topic, meta, depth
        self._outlets: list[_Outlet] = []
        self._lock = threading.Lock()
        self._last: Payload | None = None
        self.drops = 0  # stale messages a slow subscriber never got (latest-wins)
        # Subscribers the master knew when we advertised dial in a moment later; what arrives
        # before they have is kept for them, so a topic's first message is not lost (ROS 1
        # publishers drop messages for subscribers that have not connected yet).
        self._expected = 0
        self._ready_by = 0.0
        self._early: deque[Payload] = deque(maxlen=depth)

    def start(self) -> None:
        waiting = self.node.add_publisher(self)
        with self._lock:
            self._expected = len(waiting)
            self._ready_by = time.monotonic() + _EARLY_WINDOW_S

    @property
    def has_subscribers(self) -> bool:
        return bool(self._outlets)

    def accept(self, sock: socket.socket, request: dict[str, str]) -> None:
        """Finish the handshake of a subscriber that connected to the node's TCPROS port."""
        why = tcpros.check_subscriber(request, topic=self.topic, md5sum=self.meta.md5sum)
        if why:
            sock.sendall(tcpros.encode_header({"error": why}))
            sock.close()
            return
        sock.sendall(tcpros.encode_header(tcpros.publisher_header(
            caller_id=self.node.caller_id, topic=self.topic, type_name=self.meta.type,
            md5sum=self.meta.md5sum, definition=self.meta.definition, latching=self.meta.latching,
        )))
        if request.get("tcp_nodelay") == "1":
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        with self._lock:
            outlet = _Outlet(sock, self._depth, self._forget, self._dropped)
            if self.meta.latching and self._last is not None:
                outlet.put(self._last)
            elif self._early and time.monotonic() < self._ready_by:
                for data in self._early:
                    outlet.put(data)
            self._outlets.append(outlet)
            if len(self._outlets) >= self._expected:
                self._early.clear()

    def _dropped(self) -> None:
        self.drops += 1

    def _forget(self, outlet: _Outlet) -> None:
        with self._lock:
            if outlet in self._outlets:
                self._outlets.remove(outlet)

    def publish(self, data: Payload) -> None:
        with self._lock:
            if self.meta.latching:
                self._last = data
            elif len(self._outlets) < self._expected and time.monotonic() < self._ready_by:
                self._early.append(data)
            for outlet in self._outlets:
                outlet.put(data)

    def stop(self) -> None:
        self.node.remove_publisher(self)
        with self._lock:
            outlets, self._outlets = self._outlets, []
        for outlet in outlets:
            outlet.close()


class _Inlet:
    """Cancel handle of one publisher connection: sets the flag and unblocks the reader."""

    def __init__(self) -> None:
        self.stop = threading.Event()
        self.sock: socket.socket | None = None

    def cancel(self) -> None:
        self.stop.set()
        sock = self.sock
        if sock is not None:
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass


class LocalSubscription:
    """The relay subscribed to ``topic``: one reader thread per publisher (except itself)."""

    def __init__(
        self, node: RelayNode, topic: str, *,
        on_meta: Callable[[TopicMeta], None], on_message: Callable[[Payload], None],
    ) -> None:
        self.node, self.topic = node, topic
        self._on_meta, self._on_message = on_meta, on_message
        self._inlets: dict[str, _Inlet] = {}
        self._lock = threading.Lock()
        self._stopped = False

    def start(self) -> None:
        self.update(self.node.add_subscription(self))

    def update(self, publishers: list[str]) -> None:
        """Follow the master's list of publishers (``publisherUpdate``)."""
        wanted = {uri for uri in publishers if uri != self.node.uri}
        with self._lock:
            if self._stopped:
                return
            for uri in set(self._inlets) - wanted:
                self._inlets.pop(uri).cancel()
            for uri in wanted - set(self._inlets):
                inlet = self._inlets[uri] = _Inlet()
                threading.Thread(target=self._pull, args=(uri, inlet), name="relay-inlet", daemon=True).start()

    def stop(self) -> None:
        with self._lock:
            self._stopped = True
            inlets, self._inlets = self._inlets, {}
        for inlet in inlets.values():
            inlet.cancel()
        self.node.remove_subscription(self)

    def _pull(self, uri: str, inlet: _Inlet) -> None:
        """Read from one publisher until cancelled; retry while the master still lists it."""
        while not inlet.stop.is_set():
            try:
                host, port = request_topic(uri, caller_id=self.node.caller_id, topic=self.topic)
                with socket.create_connection((host, port), timeout=5.0) as sock:
                    inlet.sock = sock
                    if inlet.stop.is_set():
                        return
                    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                    sock.sendall(tcpros.encode_header(tcpros.subscriber_header(
                        caller_id=self.node.caller_id, topic=self.topic,
                        type_name=self.node.topic_type(self.topic),
                    )))
                    stream = tcpros.Stream(sock)
                    try:
                        header = tcpros.read_header(stream)
                        sock.settimeout(None)
                        self._on_meta(TopicMeta.from_header(header))
                        while not inlet.stop.is_set():
                            self._on_message(tcpros.read_message(stream))
                    finally:
                        stream.close()
            except (OSError, RelayError) as err:
                if not inlet.stop.is_set():
                    log.info("publisher %s of %s: %s; retrying", uri, self.topic, err)
                    inlet.stop.wait(0.5)
            finally:
                inlet.sock = None
