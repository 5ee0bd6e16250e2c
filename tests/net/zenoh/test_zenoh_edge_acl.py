"""The robot's own router filters too: a cloud router with NO access control (root on the host removed it)
still reaches only the manifest's topics, in their direction, and sees only the graph they need.

Real routers with fogiac's rendered configs on loopback; ROS 2 nodes stood in by zenoh-ros2-sdk
(rmw_zenoh's keys and liveliness tokens); a probe is a plain Zenoh client on one side's router.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from fogiac.procs import poll
from tests.net.zenoh.lab import IN_TOPICS, OUT_TOPICS, ZenohLab, free_ports, read_events, route

zenoh = pytest.importorskip("zenoh", reason="needs eclipse-zenoh (pip install 'fogiac[ros2]')")
pytest.importorskip("zenoh_ros2_sdk", reason="needs zenoh-ros2-sdk (pip install 'fogiac[ros2]')")
pytestmark = pytest.mark.zenoh

ROBOT_PUBS = ("/chatter_in=String", "/camera/image=Image", "/odom_secret=String")  # /odom_secret is not listed
CLOUD_PUBS = ("/result=String", "/overlay=Image", "/cmd_vel=String")  # /cmd_vel is not listed


def _open_cloud_without_acl(lab: ZenohLab, *, without: str = "cloud") -> tuple[int, int]:
    """The two routers, one of them (``without``) stripped of its access control."""
    tls_port, cloud_local, edge_local = free_ports(3)
    cloud = lab.cloud_config(route(tls_port), local_port=cloud_local)
    edge = lab.edge_config([("127.0.0.1", tls_port)], local_port=edge_local)
    del (cloud if without == "cloud" else edge)["access_control"]  # what root on the cloud host can do
    lab.router("cloud-router", cloud)
    lab.router("edge-router", edge)
    return cloud_local, edge_local


def _probe(port: int) -> Any:
    config = {"mode": "client", "connect": {"endpoints": [f"tcp/127.0.0.1:{port}"], "timeout_ms": 10000},
              "scouting": {"multicast": {"enabled": False}}}
    return zenoh.open(zenoh.Config.from_json5(json.dumps(config)))


def _tokens(session: Any) -> set[tuple[str, str]]:
    """(kind, topic or node name) of every rmw_zenoh liveliness token the session's router knows."""
    found = set()
    for reply in session.liveliness().get("@ros2_lv/**", timeout=2.0):
        if reply.ok is not None:
            chunks = str(reply.ok.key_expr).split("/")
            found.add((chunks[5], chunks[9] if len(chunks) > 9 else chunks[8]))
    return found


def test_a_cloud_router_without_access_control_gets_only_the_in_topics_and_sends_only_the_out_ones(
        tmp_path: Path) -> None:
    with ZenohLab(tmp_path) as lab:
        cloud_local, edge_local = _open_cloud_without_acl(lab)
        cloud = lab.node("cloud-node", cloud_local, pub=CLOUD_PUBS, sub=ROBOT_PUBS)
        robot = lab.node("robot", edge_local, pub=ROBOT_PUBS, sub=CLOUD_PUBS)
        # control: a second node on the robot's router does get /cmd_vel from the robot side's own publisher
        for out, topic in ((cloud, "/chatter_in"), (cloud, "/camera/image"), (robot, "/result"), (robot, "/overlay")):
            assert lab.wait_received(out, topic, count=3), f"{topic} never arrived"
        lab.wait_received(robot, "/overlay", count=10)  # the unlisted ones had as long to leak
        received = {e["topic"] for e in read_events(cloud) + read_events(robot) if e["event"] == "received"}
        assert received == {"/chatter_in", "/camera/image", "/result", "/overlay"}


@pytest.mark.parametrize("without", ["cloud", "edge"])
def test_only_the_listed_topics_endpoint_tokens_cross_and_none_can_be_forged(tmp_path: Path, without: str) -> None:
    """Either router alone keeps the graph to what the listed topics need (item 25): the cloud's router
    when the edge's is stripped (a test double), the edge's when the cloud's is (root on the host)."""
    with ZenohLab(tmp_path) as lab:
        cloud_local, edge_local = _open_cloud_without_acl(lab, without=without)
        robot = lab.node("robot", edge_local, pub=ROBOT_PUBS, sub=CLOUD_PUBS)
        cloud_probe, robot_probe = _probe(cloud_local), _probe(edge_local)
        try:
            forged = [cloud_probe.liveliness().declare_token(key) for key in (
                "@ros2_lv/0/aa/1/1/NN/%/%/evil_node",
                "@ros2_lv/0/aa/1/2/MP/%/%/evil_node/%cmd_vel/geometry_msgs::msg::dds_::Twist_/RIHS01_x/q",
                "@ros2_lv/0/aa/1/3/MP/%/%/evil_node/%result/std_msgs::msg::dds_::String_/RIHS01_x/q",
                "@ros2_lv/0/aa/1/4/SS/%/%/evil_node/%reboot/std_srvs::srv::dds_::Trigger_/RIHS01_x/q")]
            # the robot's side sees the cloud's listed publisher token (what it needs), nothing else of the cloud's
            poll(lambda: ("MP", "%result") in _tokens(robot_probe) or None, timeout=20)
            robot_side = _tokens(robot_probe)
            assert ("NN", "evil_node") not in robot_side
            assert ("MP", "%cmd_vel") not in robot_side and ("SS", "%reboot") not in robot_side
            # the cloud sees the robot's publishers of the in topics and subscribers of the out topics, only
            in_tokens = {("MP", "%" + t.strip("/").replace("/", "%")) for t in IN_TOPICS}
            out_tokens = {("MS", "%" + t.strip("/").replace("/", "%")) for t in OUT_TOPICS}
            poll(lambda: in_tokens | out_tokens <= _tokens(cloud_probe) or None, timeout=20)
            cloud_side = _tokens(cloud_probe) - {("NN", "evil_node"), ("MP", "%cmd_vel"), ("MP", "%result"),
                                                 ("SS", "%reboot")}  # its own forged ones
            assert cloud_side == in_tokens | out_tokens, "the cloud learned more of the robot's graph"
            for token in forged:
                token.undeclare()
        finally:
            cloud_probe.close()
            robot_probe.close()
        assert lab.received(robot, "/cmd_vel") == 0
