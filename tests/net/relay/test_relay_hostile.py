"""The cloud end against a hostile edge: topics outside its policy, many idle connections, a
peer that sends but never reads. Each ends that connection (or that request), nothing more."""

from __future__ import annotations

import json
import socket
import ssl
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from fogiac.net.relay import CloudConfig, CloudRelay, TopicPolicy, framing
from fogiac.net.relay.framing import Frame, Kind
from fogiac.net.relay.session import read_frame
from fogiac.net.relay.tls import client_context, expected_server_name
from tests.badinput.hostile_cloud import STRING_META
from tests.net.relay.relay_support import Master, wait_for

pytestmark = pytest.mark.ros


@pytest.fixture
def cloud(masters: tuple[Master, Master], certs: Path) -> Iterator[CloudRelay]:
    end = CloudRelay(CloudConfig(master_uri=masters[1].uri, certs=certs, ros_host="127.0.0.1",
                                 listen=("127.0.0.1", 0), poll_interval=0.1, write_timeout=1.0, max_handshakes=4,
                                 policy=TopicPolicy(out_topics=("/goal",), in_topics=("/path",))))
    end.start()
    try:
        yield end
    finally:
        end.stop()


def _edge(certs: Path, cloud: CloudRelay) -> ssl.SSLSocket:
    raw = socket.create_connection(cloud.address, timeout=5)
    sock = client_context(certs).wrap_socket(raw, server_hostname=expected_server_name(certs))
    sock.sendall(framing.encode(framing.json_frame(Kind.HELLO, {"role": "edge", "version": 1})))
    assert read_frame(sock).kind is Kind.HELLO
    return sock


def test_cloud_refuses_topics_outside_its_policy(cloud: CloudRelay, certs: Path,
                                                 masters: tuple[Master, Master]) -> None:
    with _edge(certs, cloud) as edge:
        wait_for(lambda: cloud.session is not None, 10, "the session")
        edge.sendall(framing.encode(Frame(Kind.OPEN, 1, json.dumps({**STRING_META, "topic": "/cmd_vel"}).encode())))
        edge.sendall(framing.encode(framing.json_frame(Kind.SUBSCRIBE, {"topic": "/secret"})))
        edge.sendall(framing.encode(Frame(Kind.OPEN, 2, json.dumps({**STRING_META, "topic": "/goal"}).encode())))
        wait_for(lambda: cloud.stats().refused == 2, 10, "two refusals")
        wait_for(lambda: masters[1].publishers("/goal") == ["/fogiac_relay_cloud"], 10, "the listed topic")
        assert masters[1].publishers("/cmd_vel") == [] and cloud.stats().connected
        assert "/fogiac_relay_cloud" not in masters[1].subscribers("/secret")


def test_idle_connections_cannot_pile_up_threads(cloud: CloudRelay) -> None:
    idle = [socket.create_connection(cloud.address, timeout=5) for _ in range(40)]
    try:
        wait_for(lambda: cloud.turned_away >= 36, 10, "connections beyond the cap to be turned away")
        handshaking = [t for t in threading.enumerate() if t.name == "relay-conn"]
        assert len(handshaking) <= 4
    finally:
        for sock in idle:
            sock.close()


def test_a_peer_that_never_reads_is_dropped(cloud: CloudRelay, certs: Path) -> None:
    with _edge(certs, cloud) as edge:
        edge.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        wait_for(lambda: cloud.session is not None, 10, "the session")
        session = cloud.session
        assert session is not None
        ping = framing.encode(framing.ping(0)) * 512  # each asks for a PONG we never read
        deadline = time.monotonic() + 20
        edge.settimeout(0.5)
        while session.alive and time.monotonic() < deadline:
            try:
                edge.sendall(ping)
            except (TimeoutError, ssl.SSLError, OSError):
                pass
        assert not session.alive
