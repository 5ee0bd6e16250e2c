"""The ROS 1 master and slave XML-RPC APIs, spoken directly with the stdlib.

The relay is its own ROS node (no rospy): it registers publishers and subscribers with the
master, answers ``requestTopic`` from subscribers and ``publisherUpdate`` from the master.
"""

from __future__ import annotations

import http.client
import logging
import os
import socketserver
import threading
import xmlrpc.client
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any
from xmlrpc.server import SimpleXMLRPCRequestHandler, SimpleXMLRPCServer

from fogiac.net.relay.errors import RelayError

log = logging.getLogger(__name__)


class _TimeoutTransport(xmlrpc.client.Transport):
    def __init__(self, timeout: float) -> None:
        super().__init__()
        self._timeout = timeout

    def make_connection(self, host: Any) -> http.client.HTTPConnection:
        conn = super().make_connection(host)
        conn.timeout = self._timeout
        return conn


def call(uri: str, method: str, *args: Any, timeout: float = 5.0) -> Any:
    """One XML-RPC call returning the value of a ROS ``[code, status, value]`` answer."""
    proxy = xmlrpc.client.ServerProxy(uri, transport=_TimeoutTransport(timeout), allow_none=True)
    try:
        code, status, value = getattr(proxy, method)(*args)
    except (OSError, xmlrpc.client.Error, http.client.HTTPException) as err:
        raise RelayError(f"{method} at {uri} failed: {err}") from None
    if code != 1:
        raise RelayError(f"{method} at {uri} refused: {status}")
    return value


@dataclass(frozen=True)
class Master:
    """The master of one side, called as ``caller_id``."""

    uri: str
    caller_id: str
    timeout: float = 5.0

    def _call(self, method: str, *args: Any) -> Any:
        return call(self.uri, method, self.caller_id, *args, timeout=self.timeout)

    def register_publisher(self, topic: str, type_name: str, api: str) -> list[str]:
        return list(self._call("registerPublisher", topic, type_name, api))

    def unregister_publisher(self, topic: str, api: str) -> None:
        self._call("unregisterPublisher", topic, api)

    def register_subscriber(self, topic: str, type_name: str, api: str) -> list[str]:
        return list(self._call("registerSubscriber", topic, type_name, api))

    def unregister_subscriber(self, topic: str, api: str) -> None:
        self._call("unregisterSubscriber", topic, api)

    def system_state(self) -> Any:
        return self._call("getSystemState")

    def topic_types(self) -> dict[str, str]:
        return dict(self._call("getTopicTypes"))


def request_topic(publisher_api: str, *, caller_id: str, topic: str) -> tuple[str, int]:
    """Where a publisher serves ``topic`` over TCPROS."""
    value = call(publisher_api, "requestTopic", caller_id, topic, [["TCPROS"]])
    if not value or value[0] != "TCPROS" or len(value) < 3:
        raise RelayError(f"{publisher_api} offered no TCPROS for {topic}: {value!r}")
    return str(value[1]), int(value[2])


@dataclass(frozen=True)
class SlaveHandlers:
    """What the node does when the master or a peer node calls it."""

    publisher_update: Callable[[str, list[str]], None]
    tcpros_endpoint: Callable[[str], tuple[str, int] | None]
    publications: Callable[[], list[list[str]]]
    subscriptions: Callable[[], list[list[str]]]


class _Quiet(SimpleXMLRPCRequestHandler):
    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - stdlib signature
        log.debug("xmlrpc: " + format, *args)


class _Server(socketserver.ThreadingMixIn, SimpleXMLRPCServer):
    daemon_threads = True
    allow_reuse_address = True


class SlaveServer:
    """The node's slave API on an ephemeral port; ``uri`` is what the master is told."""

    def __init__(self, *, bind: str, host: str, caller_id: str, master_uri: str, handlers: SlaveHandlers) -> None:
        self._server = _Server((bind, 0), requestHandler=_Quiet, logRequests=False, allow_none=True)
        self.uri = f"http://{host}:{self._server.server_address[1]}/"
        self._caller_id, self._master_uri, self._h = caller_id, master_uri, handlers
        for name in (
            "getBusStats", "getBusInfo", "getMasterUri", "shutdown", "getPid", "getSubscriptions",
            "getPublications", "paramUpdate", "publisherUpdate", "requestTopic",
        ):
            self._server.register_function(getattr(self, name), name)
        self._thread = threading.Thread(target=self._server.serve_forever, name="relay-slave", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._server.shutdown()
        self._server.server_close()

    def getBusStats(self, caller_id: str) -> list[Any]:
        return [1, "", [[], [], []]]

    def getBusInfo(self, caller_id: str) -> list[Any]:
        return [1, "", []]

    def getMasterUri(self, caller_id: str) -> list[Any]:
        return [1, "", self._master_uri]

    def shutdown(self, caller_id: str, msg: str = "") -> list[Any]:
        log.warning("master asked %s to shut down (%s); another node took its name", self._caller_id, msg)
        return [1, "", 0]

    def getPid(self, caller_id: str) -> list[Any]:
        return [1, "", os.getpid()]

    def getSubscriptions(self, caller_id: str) -> list[Any]:
        return [1, "", self._h.subscriptions()]

    def getPublications(self, caller_id: str) -> list[Any]:
        return [1, "", self._h.publications()]

    def paramUpdate(self, caller_id: str, key: str, value: Any) -> list[Any]:
        return [1, "", 0]

    def publisherUpdate(self, caller_id: str, topic: str, publishers: list[str]) -> list[Any]:
        self._h.publisher_update(topic, list(publishers))
        return [1, "", 0]

    def requestTopic(self, caller_id: str, topic: str, protocols: list[Any]) -> list[Any]:
        endpoint = self._h.tcpros_endpoint(topic)
        if endpoint is None:
            return [-1, f"not a publisher of {topic}", []]
        if not any(p and p[0] == "TCPROS" for p in protocols):
            return [0, "only TCPROS is supported", []]
        return [1, "", ["TCPROS", endpoint[0], endpoint[1]]]
