"""The relay as a ROS 1 node: a slave API, a TCPROS port, and its topic registrations.

One node per end, alive across link reconnects; each relayed topic registers through it so
the master sees a single, well-named caller (``/fogiac_relay_edge`` or ``/fogiac_relay_cloud``)
whose registrations both ends leave out of discovery.
"""

from __future__ import annotations

import ipaddress
import logging
import socket
import threading
from collections.abc import Mapping
from typing import TYPE_CHECKING

from fogiac.net.relay import tcpros
from fogiac.net.relay.errors import RelayError
from fogiac.net.relay.rosapi import Master, SlaveHandlers, SlaveServer

if TYPE_CHECKING:
    from fogiac.net.relay.pubsub import LocalPublisher, LocalSubscription

log = logging.getLogger(__name__)


def _bind_address(host: str) -> str:
    try:
        ipaddress.ip_address(host)
    except ValueError:
        return ""
    return host


class RelayNode:
    def __init__(self, *, master_uri: str, caller_id: str, host: str) -> None:
        self.caller_id, self.host = caller_id, host
        self.master = Master(master_uri, caller_id)
        self._publishers: dict[str, LocalPublisher] = {}
        self._subscriptions: dict[str, LocalSubscription] = {}
        self._types: dict[str, str] = {}
        self._hints: dict[str, str] = {}  # topic -> type told to the master for rostopic (see hint_types)
        self._lock = threading.Lock()
        bind = _bind_address(host)
        self._slave = SlaveServer(bind=bind, host=host, caller_id=caller_id, master_uri=master_uri,
                                  handlers=SlaveHandlers(self._publisher_update, self._endpoint,
                                                         self._publications, self._subscription_list))
        self.uri = self._slave.uri
        self._listener = socket.create_server((bind, 0), backlog=64)
        self.tcpros_port = self._listener.getsockname()[1]
        self._closed = False

    def start(self) -> None:
        self._slave.start()
        threading.Thread(target=self._accept_loop, name="relay-tcpros", daemon=True).start()

    def stop(self) -> None:
        self._closed = True
        for pub in list(self._publishers.values()):
            pub.stop()
        for sub in list(self._subscriptions.values()):
            sub.stop()
        self._listener.close()
        self._slave.stop()

    # --- registrations -------------------------------------------------------------------
    def add_publisher(self, pub: LocalPublisher) -> list[str]:
        """Register ``pub``; returns the subscribers the master already knows (they will dial in)."""
        with self._lock:
            if pub.topic in self._publishers:
                raise RelayError(f"{self.caller_id} already publishes {pub.topic}")
            self._publishers[pub.topic] = pub
        return self.master.register_publisher(pub.topic, pub.meta.type, self.uri)

    def remove_publisher(self, pub: LocalPublisher) -> None:
        with self._lock:
            if self._publishers.get(pub.topic) is not pub:
                return
            del self._publishers[pub.topic]
        self._quietly(self.master.unregister_publisher, pub.topic)

    def add_subscription(self, sub: LocalSubscription) -> list[str]:
        with self._lock:
            if sub.topic in self._subscriptions:
                raise RelayError(f"{self.caller_id} already subscribes {sub.topic}")
            self._subscriptions[sub.topic] = sub
        try:
            self._types.update(self.master.topic_types())
        except RelayError as err:
            log.info("getTopicTypes: %s", err)
        return self.master.register_subscriber(sub.topic, "*", self.uri)

    def remove_subscription(self, sub: LocalSubscription) -> None:
        with self._lock:
            if self._subscriptions.get(sub.topic) is not sub:
                return
            del self._subscriptions[sub.topic]
        self._quietly(self.master.unregister_subscriber, sub.topic)

    def hint_types(self, hints: Mapping[str, str]) -> None:
        """Tell the master these topics' types (the far side publishes them), by registering as a typed
        subscriber: ``rostopic echo`` asks the master for the type before it subscribes. A topic whose
        route starts gets its real publisher (with the md5 and definition) from the far side's OPEN."""
        wanted = {t: ty for t, ty in hints.items() if t not in self._subscriptions}
        for topic in sorted(set(self._hints) - set(wanted)):
            if topic not in self._subscriptions:
                self._quietly(self.master.unregister_subscriber, topic)
            del self._hints[topic]
        for topic, type_name in sorted(wanted.items()):
            if self._hints.get(topic) != type_name:
                try:
                    self.master.register_subscriber(topic, type_name, self.uri)
                except RelayError as err:
                    log.info("%s: cannot tell the master its type: %s", topic, err)
                    continue
                self._hints[topic] = type_name

    def register_all(self) -> None:
        """Register every publication and subscription again (the master restarted empty)."""
        for topic, type_name in sorted(self._hints.items()):
            self.master.register_subscriber(topic, type_name, self.uri)
        for pub in list(self._publishers.values()):
            self.master.register_publisher(pub.topic, pub.meta.type, self.uri)
        for sub in list(self._subscriptions.values()):
            sub.update(self.master.register_subscriber(sub.topic, "*", self.uri))

    def topic_type(self, topic: str) -> str:
        return self._types.get(topic, "*")

    def publisher(self, topic: str) -> LocalPublisher | None:
        return self._publishers.get(topic)

    def _quietly(self, method: object, topic: str) -> None:
        try:
            method(topic, self.uri)  # type: ignore[operator]
        except RelayError as err:
            log.warning("%s: %s", topic, err)

    # --- slave API callbacks -------------------------------------------------------------
    def _publisher_update(self, topic: str, publishers: list[str]) -> None:
        sub = self._subscriptions.get(topic)
        if sub is not None:
            sub.update(publishers)

    def _endpoint(self, topic: str) -> tuple[str, int] | None:
        return (self.host, self.tcpros_port) if topic in self._publishers else None

    def _publications(self) -> list[list[str]]:
        return [[t, p.meta.type] for t, p in sorted(self._publishers.items())]

    def _subscription_list(self) -> list[list[str]]:
        return [[t, self.topic_type(t)] for t in sorted(self._subscriptions)]

    # --- TCPROS server -------------------------------------------------------------------
    def _accept_loop(self) -> None:
        while not self._closed:
            try:
                sock, _ = self._listener.accept()
            except OSError:
                return
            threading.Thread(target=self._handshake, args=(sock,), name="relay-handshake", daemon=True).start()

    def _handshake(self, sock: socket.socket) -> None:
        try:
            sock.settimeout(5.0)
            request = tcpros.read_header(tcpros.Stream(sock, buffer=0))
            sock.settimeout(None)
            pub = self._publishers.get(request.get("topic", ""))
            if pub is None:
                why = f"{self.caller_id} does not publish {request.get('topic')}"
                sock.sendall(tcpros.encode_header({"error": why}))
                sock.close()
                return
            pub.accept(sock, request)
        except (OSError, RelayError) as err:
            log.info("TCPROS handshake failed: %s", err)
            sock.close()
