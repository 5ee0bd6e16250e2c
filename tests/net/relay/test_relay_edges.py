"""One cloud end, two edges of different identities (two robots, each its own roscore and certificate):
both linked at once, each with its own traffic; a newer session of one identity replaces only its own."""

from __future__ import annotations

import contextlib
import shutil
import socket
from collections.abc import Iterator
from pathlib import Path

import pytest

from fogiac.certs import edge_identity, edge_role, load_or_create_edges
from fogiac.net.relay import CloudConfig, CloudRelay, EdgeConfig, EdgeRelay, TopicPolicy, framing
from fogiac.net.relay.framing import Kind
from fogiac.net.relay.session import read_frame
from fogiac.net.relay.tls import client_context, expected_server_name
from tests.net.relay.relay_support import Master, Procs, indices, wait_for

pytestmark = pytest.mark.ros

STACK = "relaytest"  # the lab certificates' stack (conftest's ``certs``)
SECOND = "arm2"


@pytest.fixture
def edge_certs(certs: Path, tmp_path: Path) -> Path:
    """The lab folder with a second edge's pair, issued the way ``up`` issues every edge's."""
    folder = tmp_path / "certs"
    shutil.copytree(certs, folder)
    load_or_create_edges(STACK, folder, [None, SECOND])  # None: the stack's one edge of today
    for name in ("server.pem", "server.key"):  # the lab's cloud end pair, which a stack's folder never keeps
        shutil.copy(certs / name, folder / name)
    return folder


@contextlib.contextmanager
def linked(cloud_master: Master, edges: list[tuple[Master, str]], certs: Path) -> Iterator[tuple[CloudRelay,
                                                                                            list[EdgeRelay]]]:
    cloud = CloudRelay(CloudConfig(master_uri=cloud_master.uri, certs=certs, ros_host="127.0.0.1",
                                   listen=("127.0.0.1", 0), poll_interval=0.1, policy=TopicPolicy(auto=True)))
    cloud.start()
    ends: list[EdgeRelay] = []
    try:
        for n, (master, client) in enumerate(edges):
            end = EdgeRelay(EdgeConfig(master_uri=master.uri, certs=certs, client=client, ros_host="127.0.0.1",
                                       connect=cloud.address, poll_interval=0.1, backoff_initial=0.1,
                                       backoff_max=0.5, caller_id=f"/fogiac_relay_edge_{n}"))
            end.start()
            ends.append(end)
        yield cloud, ends
    finally:
        for end in ends:
            end.stop()
        cloud.stop()


def _texts(data: list[bytes]) -> set[str]:
    return {raw[4:].decode().split(" ")[0] for raw in data}


def test_two_edges_are_linked_at_once_each_with_its_own_traffic(masters: tuple[Master, Master], edge_certs: Path,
                                                                 procs: Procs) -> None:
    robot_a, cloud_m = masters
    robot_b = procs.roscore()
    ids = {edge_identity(STACK, None), edge_identity(STACK, SECOND)}
    with linked(cloud_m, [(robot_a, "client"), (robot_b, edge_role(STACK, SECOND))], edge_certs) as (cloud, ends):
        wait_for(lambda: all(e.connected.is_set() for e in ends) and len(cloud.sessions) == 2, 15, "both links")
        assert set(cloud.sessions) == ids and all(s.alive for s in cloud.sessions.values())
        # Each robot's own topic up, and one topic both robots send (one publisher on the cloud's master).
        procs.node(robot_a, "pub", "/a_up", "--forever", "--rate", "40")
        procs.node(robot_b, "pub", "/b_up", "--forever", "--rate", "40")
        procs.node(robot_a, "pub", "/both_up", "--forever", "--rate", "40", "--prefix", "a")
        procs.node(robot_b, "pub", "/both_up", "--forever", "--rate", "40", "--prefix", "b")
        a_up = procs.node(cloud_m, "sub", "/a_up", "--count", "100000")
        b_up = procs.node(cloud_m, "sub", "/b_up", "--count", "100000")
        both_up = procs.node(cloud_m, "sub", "/both_up", "--count", "100000")
        # Down: one topic only robot A asks for, and one both ask for (one subscription on the cloud's master).
        procs.node(cloud_m, "pub", "/a_down", "--forever", "--rate", "40")
        procs.node(cloud_m, "pub", "/both_down", "--forever", "--rate", "40")
        a_down = procs.node(robot_a, "sub", "/a_down", "--count", "100000")
        a_both = procs.node(robot_a, "sub", "/both_down", "--count", "100000")
        b_both = procs.node(robot_b, "sub", "/both_down", "--count", "100000")
        wait_for(lambda: all(len(p.data()) >= 20 for p in (a_up, b_up, a_down, a_both, b_both))
                 and _texts(both_up.data()) == {"a", "b"}, 40, "every route, both robots' /both_up")
        assert cloud_m.publishers("/both_up") == ["/fogiac_relay_cloud"]  # the two sessions' one publisher
        assert cloud_m.subscribers("/both_down").count("/fogiac_relay_cloud") == 1
        assert robot_b.publishers("/a_down") == []  # robot B never asked for A's topic
        for proc in (a_up, b_up, a_down, a_both, b_both):
            got = indices(proc.data())
            assert got == list(range(got[0], got[0] + len(got)))  # in order, nothing repeated or lost
        assert cloud.reconnects == 0 and all(e.reconnects == 0 for e in ends)
        assert {t.topic for t in cloud.stats().topics} >= {"/a_up", "/b_up", "/both_up", "/a_down", "/both_down"}


def _hello(certs: Path, client: str, address: tuple[str, int]) -> socket.socket:
    """A bare edge with ``client``'s certificate: TLS and HELLO, then nothing."""
    raw = socket.create_connection(address, timeout=5)
    sock = client_context(certs, client).wrap_socket(raw, server_hostname=expected_server_name(certs))
    sock.sendall(framing.encode(framing.json_frame(Kind.HELLO, {"role": "edge", "version": 1})))
    assert read_frame(sock).kind is Kind.HELLO
    return sock


def test_a_newer_session_replaces_only_its_own_identity(masters: tuple[Master, Master], edge_certs: Path,
                                                        procs: Procs) -> None:
    robot_a, cloud_m = masters
    robot_b = procs.roscore()
    first, second = edge_identity(STACK, None), edge_identity(STACK, SECOND)
    with linked(cloud_m, [(robot_a, "client"), (robot_b, edge_role(STACK, SECOND))], edge_certs) as (cloud, ends):
        wait_for(lambda: len(cloud.sessions) == 2 and all(e.connected.is_set() for e in ends), 15, "both links")
        procs.node(robot_b, "pub", "/b_steady", "--forever", "--rate", "40")
        steady = procs.node(cloud_m, "sub", "/b_steady", "--count", "100000")
        wait_for(lambda: len(steady.data()) >= 10, 30, "robot B's flow")
        a_old, b_session = cloud.sessions[first], cloud.sessions[second]
        # Robot A's certificate again: a newer session of A (robot A's relay, cut off, redials and replaces
        # that one in turn).
        with _hello(edge_certs, "client", cloud.address):
            wait_for(lambda: cloud.sessions[first] is not a_old, 10, "the newer session of A")
            assert not a_old.alive and cloud.reconnects >= 1
            assert cloud.sessions[second] is b_session and b_session.alive
            before = len(steady.data())
            wait_for(lambda: len(steady.data()) >= before + 20, 20, "robot B's flow to go on")
        wait_for(lambda: ends[0].connected.is_set() and ends[0].reconnects >= 1 and cloud.sessions[first].alive,
                 20, "robot A's relay back")
        assert cloud.sessions[second] is b_session and b_session.alive and ends[1].reconnects == 0
        got = indices(steady.data())
        assert got == list(range(got[0], got[0] + len(got)))
