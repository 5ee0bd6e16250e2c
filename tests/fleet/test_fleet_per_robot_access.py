"""Issue 34, ROS 1: a per-robot node's instances' topics cross for their own robot only, by the access file.

The cloud end's topic policy names no robot (a robot added must not restart it), so the access file's
``per_robot`` entry says which topics a per-robot node lists (``/scan`` in, ``/slam/count`` out); robot arm1
may send ``/arm1/scan`` and hear ``/arm1/slam/count``, and nothing of arm2's instance, the other way round,
or once revoked. A real roscore on the cloud side, a bare edge with each robot's certificate.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from fogiac.certs import edge_identity
from fogiac.net.relay import framing
from fogiac.net.relay.config import policy_from_spec
from fogiac.net.relay.fleet import ACCESS_FILE, FleetAccess, PerRobot, read_access, write_access
from fogiac.net.relay.framing import Kind
from tests.fleet.fleet_support import STACK, access, cloud_end
from tests.fleet.test_fleet_relay_access import _hello, _send
from tests.net.relay.relay_support import Master, wait_for

pytestmark = pytest.mark.ros

SLAM = PerRobot("slam", frozenset({"/scan"}), frozenset({"/slam/count"}))
HEADER_MD5 = "2176decaecbce78abc3b96ef049fabed"  # std_msgs/Header


def _with_slam(revoked: tuple[str, ...] = ()) -> FleetAccess:
    rules = access(revoked=revoked)
    return FleetAccess(rules.robots, rules.revoked, rules.shared, (SLAM,))


def test_the_access_file_keeps_per_robot_nodes_and_says_whose_instance_a_topic_is(tmp_path: Path) -> None:
    path = tmp_path / ACCESS_FILE
    write_access(path, _with_slam())
    rules = read_access(path)
    assert rules is not None and rules.per_robot == (SLAM,)
    arm1, arm2 = edge_identity(STACK, "arm1"), edge_identity(STACK, "arm2")
    assert rules.crosses(arm1, "/arm1/scan", "out") and rules.crosses(arm1, "/arm1/slam/count", "in")
    assert not rules.crosses(arm1, "/arm1/scan", "in")  # it sends scans; it does not hear them from the cloud
    assert not rules.crosses(arm1, "/arm1/slam/count", "out")  # nor pose as its instance
    assert not rules.crosses(arm1, "/arm2/scan", "out") and not rules.crosses(arm2, "/arm1/slam/count", "in")
    assert not rules.crosses(arm1, "/scan", "out")  # the bare name is no robot's
    assert not _with_slam(revoked=("arm1",)).crosses(arm1, "/arm1/scan", "out")


def test_a_robot_reaches_its_own_instance_only(masters: tuple[Master, Master], fleet_certs: Path) -> None:
    _, cloud_m = masters
    write_access(fleet_certs / ACCESS_FILE, _with_slam())
    arm1 = edge_identity(STACK, "arm1")
    policy = policy_from_spec("")  # the cloud end's own policy lets nothing cross: only the access file does
    with cloud_end(cloud_m, fleet_certs, policy) as cloud, _hello(fleet_certs, "arm1", cloud.address) as sock:
        wait_for(lambda: arm1 in cloud.sessions, 10, "arm1's session")
        session = cloud.sessions[arm1]
        _send(sock, Kind.OPEN, "/arm2/scan")  # feed arm2's instance
        _send(sock, Kind.SUBSCRIBE, "/arm2/slam/count")  # read arm2's instance's state
        _send(sock, Kind.SUBSCRIBE, "/arm1/scan")  # its own topic, the wrong way
        sock.sendall(framing.encode(framing.json_frame(Kind.OPEN, {  # its own instance's input
            "topic": "/arm1/scan", "compression": "none", "type": "std_msgs/Header", "latching": False,
            "md5sum": HEADER_MD5}, topic=8)))
        _send(sock, Kind.SUBSCRIBE, "/arm1/slam/count")  # and its output
        wait_for(lambda: session.refused == 3 and "/fogiac_relay_cloud" in cloud_m.subscribers("/arm1/slam/count")
                 and "/fogiac_relay_cloud" in cloud_m.publishers("/arm1/scan"), 10,
                 "three refusals and arm1's own instance's topics")
        assert "/fogiac_relay_cloud" not in cloud_m.publishers("/arm2/scan")
        assert "/fogiac_relay_cloud" not in cloud_m.subscribers("/arm2/slam/count")
        assert session.alive
