"""Issue 34, ROS 1: a fleet's cloud end links each robot by its own certificate and only for its own topics.

Three robots, each its own roscore, certificate and relay edge end, link to one cloud end that follows the
access file beside its certificates (``fleet.json``). A robot asking for or sending another robot's topic is
refused; revoking a robot in the file closes its link and refuses its redials within 10 s while the others
carry on; restoring it links it again; no process is restarted. A shared node's topics are used one way only.
"""

from __future__ import annotations

import contextlib
import socket
from pathlib import Path

import pytest

from fogiac.certs import edge_identity, edge_role
from fogiac.net.relay import EdgeRelay, framing
from fogiac.net.relay.config import policy_from_spec
from fogiac.net.relay.fleet import ACCESS_FILE, SharedPair, write_access
from fogiac.net.relay.framing import Kind
from fogiac.net.relay.session import read_frame
from fogiac.net.relay.tls import client_context, expected_server_name
from tests.fleet.fleet_support import STACK, access, cloud_end, edge_end
from tests.net.relay.relay_support import Master, Procs, wait_for

pytestmark = pytest.mark.ros


def _hello(certs: Path, robot: str | None, address: tuple[str, int], *, answered: bool = True) -> socket.socket:
    """A bare edge with ``robot``'s certificate (None: the shorthand's one edge): TLS and HELLO, and the cloud's
    HELLO back (``answered``; else the caller reads what the cloud does instead)."""
    raw = socket.create_connection(address, timeout=5)
    sock = client_context(certs, edge_role(STACK, robot)).wrap_socket(raw, server_hostname=expected_server_name(certs))
    sock.sendall(framing.encode(framing.json_frame(Kind.HELLO, {"role": "edge", "version": 1})))
    if answered:
        assert read_frame(sock).kind is Kind.HELLO
    return sock


def _send(sock: socket.socket, kind: Kind, topic: str) -> None:
    sock.sendall(framing.encode(framing.json_frame(kind, {"topic": topic, "compression": "none"}, topic=7)))


def test_a_robot_is_refused_another_robots_topics(masters: tuple[Master, Master], fleet_certs: Path) -> None:
    _, cloud_m = masters
    arm1 = edge_identity(STACK, "arm1")
    # The topic policy lets all four cross: only the fleet's rules refuse.
    policy = policy_from_spec("auto", in_topics="/arm1/scan,/arm2/scan,/plan/reply", out_topics="/arm2/cmd_vel")
    with cloud_end(cloud_m, fleet_certs, policy) as cloud, _hello(fleet_certs, "arm1", cloud.address) as sock:
        wait_for(lambda: arm1 in cloud.sessions, 10, "arm1's session")
        session = cloud.sessions[arm1]
        _send(sock, Kind.SUBSCRIBE, "/arm2/scan")  # read another robot's topic
        _send(sock, Kind.OPEN, "/arm2/cmd_vel")  # publish on another robot's topic
        _send(sock, Kind.SUBSCRIBE, "/arm1/scan")  # its own namespace
        _send(sock, Kind.SUBSCRIBE, "/plan/reply")  # the shared node's reply topic
        wait_for(lambda: session.refused == 2 and "/fogiac_relay_cloud" in cloud_m.subscribers("/plan/reply"),
                 10, "two refusals and the allowed subscriptions")
        assert "/fogiac_relay_cloud" in cloud_m.subscribers("/arm1/scan")
        assert "/fogiac_relay_cloud" not in cloud_m.subscribers("/arm2/scan")
        assert "/fogiac_relay_cloud" not in cloud_m.publishers("/arm2/cmd_vel")
        assert session.alive  # a refusal is counted and logged; the link stays
        assert cloud.stats().refused == 2
        # A certificate of the same CA that names no robot of the fleet (the shorthand's one edge) is not linked.
        before = cloud.refused_links
        with _hello(fleet_certs, None, cloud.address, answered=False) as stranger:
            stranger.settimeout(10)
            refused = read_frame(stranger)  # no HELLO back (it never counts itself linked): the reason, and closed
            assert (refused.kind, framing.parse_json(refused)) == (Kind.REFUSE, {"reason": "not a robot of this fleet"})
            assert stranger.recv(1) == b""
        assert cloud.refused_links == before + 1 and edge_identity(STACK, None) not in cloud.sessions


def test_a_revoked_robot_is_cut_off_within_10_s_and_restored(masters: tuple[Master, Master], fleet_certs: Path,
                                                             procs: Procs) -> None:
    first, cloud_m = masters
    robots = {"arm1": first, "arm2": procs.roscore(), "arm3": procs.roscore()}
    with cloud_end(cloud_m, fleet_certs) as cloud, contextlib.ExitStack() as stack:
        ends: dict[str, EdgeRelay] = {}
        for n, (name, master) in enumerate(robots.items()):
            end = ends[name] = edge_end(name, master, fleet_certs, cloud, n)
            stack.callback(end.stop)
        ups = {}
        for name, master in robots.items():  # each robot's own client process, and its listener in the cloud
            procs.node(master, "pub", f"/{name}/up", "--forever", "--rate", "40")
            ups[name] = procs.node(cloud_m, "sub", f"/{name}/up", "--count", "100000")
        # arm1's master also subscribes to arm2's topic: arm1 never hears of it (the cloud's graph is filtered).
        spy = procs.node(robots["arm1"], "sub", "/arm2/up", "--count", "100000")
        wait_for(lambda: all(len(p.data()) >= 10 for p in ups.values()), 40, "every robot's flow")
        assert spy.data() == [] and cloud_m.publishers("/arm2/up") == ["/fogiac_relay_cloud"]
        assert robots["arm1"].publishers("/arm2/up") == []

        arm3 = edge_identity(STACK, "arm3")
        session = cloud.sessions[arm3]
        write_access(fleet_certs / ACCESS_FILE, access(revoked=("arm3",)))
        wait_for(lambda: not session.alive, 10, "arm3's link closed")
        wait_for(lambda: cloud.refused_links >= 1, 10, "arm3's redial refused")
        assert not cloud.sessions[arm3].alive
        # its redials are refused before the cloud's HELLO: arm3's edge never counts itself linked again
        wait_for(lambda: ends["arm3"].reconnects >= 1, 10, "arm3's link ended at its edge")
        assert not ends["arm3"].connected.is_set()
        cut = len(ups["arm3"].data())
        counts = {n: len(ups[n].data()) for n in ("arm1", "arm2")}
        wait_for(lambda: all(len(ups[n].data()) >= counts[n] + 20 for n in counts), 20, "arm1 and arm2 carry on")
        assert len(ups["arm3"].data()) <= cut + 1  # at most one message in flight when the link was cut
        assert all(cloud.sessions[edge_identity(STACK, n)].alive for n in ("arm1", "arm2"))

        write_access(fleet_certs / ACCESS_FILE, access())  # restored: its edge's next redial is linked
        wait_for(lambda: cloud.sessions[arm3].alive and ends["arm3"].connected.is_set(), 15, "arm3 back")
        wait_for(lambda: len(ups["arm3"].data()) >= cut + 10, 20, "arm3's flow again")


def test_a_robot_uses_a_shared_nodes_topics_one_way(masters: tuple[Master, Master], fleet_certs: Path) -> None:
    """A shared node named in the file: a robot sends its requests and hears its replies, but may not read the
    request topic (every robot's requests) nor publish on the reply topic (posing as the node)."""
    _, cloud_m = masters
    planner = SharedPair("planner", frozenset({"/plan/request"}), frozenset({"/plan/reply"}))
    write_access(fleet_certs / ACCESS_FILE, access(shared=(planner,)))
    arm2 = edge_identity(STACK, "arm2")
    policy = policy_from_spec("auto", in_topics="/plan/request,/plan/reply", out_topics="/plan/reply")
    with cloud_end(cloud_m, fleet_certs, policy) as cloud, _hello(fleet_certs, "arm2", cloud.address) as sock:
        wait_for(lambda: arm2 in cloud.sessions, 10, "arm2's session")
        session = cloud.sessions[arm2]
        _send(sock, Kind.SUBSCRIBE, "/plan/request")  # read every robot's requests
        _send(sock, Kind.OPEN, "/plan/reply")  # answer in the node's name
        _send(sock, Kind.SUBSCRIBE, "/plan/reply")  # hear its replies: allowed
        wait_for(lambda: session.refused == 2 and "/fogiac_relay_cloud" in cloud_m.subscribers("/plan/reply"),
                 10, "two refusals and the reply subscription")
        assert "/fogiac_relay_cloud" not in cloud_m.subscribers("/plan/request")
        assert "/fogiac_relay_cloud" not in cloud_m.publishers("/plan/reply") and session.alive
