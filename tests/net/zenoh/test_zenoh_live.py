"""Real Zenoh routers opened with fogiac's rendered configs, ROS 2 nodes stood in by zenoh-ros2-sdk.

All on loopback: the cloud router (mutual TLS for the edge, TCP on loopback for its nodes, access
control), the edge router (dials out), one "robot" process on the edge router and one "cloud node"
process on the cloud router, as rmw_zenoh nodes connect.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from fogiac.certs import new_ca
from fogiac.net.zenoh import tls
from fogiac.net.zenoh.config import cloud_router
from fogiac.net.zenoh.errors import ZenohError
from fogiac.net.zenoh.router import open_router
from fogiac.procs import poll
from tests.net.zenoh.lab import STACK, ZenohLab, free_ports, read_events, route

zenoh = pytest.importorskip("zenoh", reason="needs eclipse-zenoh (pip install 'fogiac[ros2]')")
pytest.importorskip("zenoh_ros2_sdk", reason="needs zenoh-ros2-sdk (pip install 'fogiac[ros2]')")
pytestmark = pytest.mark.zenoh

ROBOT_PUBS = ("/chatter_in=String", "/camera/image=Image", "/cmd_vel=String")  # /cmd_vel is not listed
CLOUD_PUBS = ("/result=String", "/overlay=Image", "/leak_out=String")  # /leak_out is not listed


def _sent(out: Path) -> dict[tuple[str, int], str]:
    return {(e["topic"], e["seq"]): e["sha256"] for e in read_events(out) if e["event"] == "sent"}


def _start(lab: ZenohLab) -> tuple[Path, Path, int, dict]:
    tls_port, cloud_local, edge_local = free_ports(3)
    cloud_config = lab.cloud_config(route(tls_port), local_port=cloud_local)
    lab.router("cloud-router", cloud_config)
    lab.router("edge-router", lab.edge_config([("127.0.0.1", tls_port)], local_port=edge_local))
    cloud = lab.node("cloud-node", cloud_local, pub=CLOUD_PUBS, sub=ROBOT_PUBS)
    robot = lab.node("robot", edge_local, pub=ROBOT_PUBS, sub=CLOUD_PUBS)
    return cloud, robot, cloud_local, cloud_config


def test_listed_topics_cross_byte_exact_both_ways_and_unlisted_ones_do_not(tmp_path: Path) -> None:
    with ZenohLab(tmp_path) as lab:
        cloud, robot, cloud_local, _ = _start(lab)
        # control: a second node on the cloud host does get /leak_out, through the same router
        neighbour = lab.node("cloud-neighbour", cloud_local, sub=("/leak_out=String",))
        for out, topic in ((cloud, "/chatter_in"), (cloud, "/camera/image"), (robot, "/result"), (robot, "/overlay")):
            assert lab.wait_received(out, topic, count=3), f"{topic} never arrived"
        assert lab.wait_received(neighbour, "/leak_out", count=3)
        lab.wait_received(robot, "/overlay", count=8)  # the unlisted ones had as long to leak

        sent = {**_sent(cloud), **_sent(robot)}
        received = [e for e in read_events(cloud) + read_events(robot) if e["event"] == "received"]
        assert {e["topic"] for e in received} == {"/chatter_in", "/camera/image", "/result", "/overlay"}
        for event in received:  # byte-exact: the CDR bytes received are the bytes sent for that seq
            assert event["sha256"] == sent[(event["topic"], event["seq"])], event


def _client(config: dict) -> dict:  # a client fails at open when it cannot connect, a router retries
    return dict(config, mode="client", listen={"endpoints": []},
                connect={"endpoints": config["connect"]["endpoints"], "timeout_ms": 3000})


def test_an_edge_with_a_certificate_from_another_ca_is_refused(tmp_path: Path) -> None:
    with ZenohLab(tmp_path) as lab:
        tls_port, cloud_local, edge_local = free_ports(3)
        lab.router("cloud-router", lab.cloud_config(route(tls_port), local_port=cloud_local))
        good = open_router(_client(lab.edge_config([("127.0.0.1", tls_port)], local_port=edge_local)))
        good.close()
        stranger = lab.edge_config([("127.0.0.1", tls_port)], local_port=edge_local, ca=new_ca("another CA"))
        with pytest.raises(ZenohError, match="Unable to connect"):
            open_router(_client(stranger))


def test_an_edge_refuses_a_router_whose_certificate_names_another_address(tmp_path: Path) -> None:
    """Why the certificate must name what the edge dials (a VPC's private address over the VPN)."""
    with ZenohLab(tmp_path) as lab:
        tls_port, cloud_local, edge_local = free_ports(3)
        files = lab.host_files("elsewhere", address="10.10.1.5")  # the edge dials 127.0.0.1 below
        lab.router("cloud-router", cloud_router(route(tls_port), listen_host="127.0.0.1", tls=files,
                                                edge_name=tls.edge_name(STACK), local_port=cloud_local))
        with pytest.raises(ZenohError, match="Unable to connect"):
            open_router(_client(lab.edge_config([("127.0.0.1", tls_port)], local_port=edge_local)))
        assert Path(files.key).stat().st_mode & 0o777 == 0o600


def test_the_flow_resumes_when_the_cloud_router_restarts_without_touching_the_edge(tmp_path: Path) -> None:
    with ZenohLab(tmp_path) as lab:
        cloud, robot, _, cloud_config = _start(lab)
        cloud_router, edge_router = lab.procs[0], lab.procs[1]
        assert lab.wait_received(robot, "/result", count=3)
        lab.stop(cloud_router, kill=True)  # SIGKILL: no goodbye to the edge
        results, chats = lab.received(robot, "/result"), lab.received(cloud, "/chatter_in")
        lab.router("cloud-router-again", cloud_config)
        assert lab.wait_received(robot, "/result", count=results + 5), "no /result after the restart"
        assert lab.wait_received(cloud, "/chatter_in", count=chats + 5), "no /chatter_in after the restart"
        assert edge_router.poll() is None  # the same edge router process throughout


@pytest.mark.skipif(shutil.which("ss") is None, reason="needs ss (iproute2)")
def test_the_edge_router_dials_out_and_listens_on_loopback_only(tmp_path: Path) -> None:
    with ZenohLab(tmp_path) as lab:
        tls_port, cloud_local, edge_local = free_ports(3)
        lab.router("cloud-router", lab.cloud_config(route(tls_port), local_port=cloud_local))
        edge = lab.router("edge-router", lab.edge_config([("127.0.0.1", tls_port)], local_port=edge_local))
        mine = f"pid={edge.pid},"

        def sockets(flags: str) -> list[str]:
            out = subprocess.run(["ss", "-Hn" + flags + "p"], capture_output=True, text=True, check=True).stdout
            return [line for line in out.splitlines() if mine in line]

        listening = [re.split(r"\s+", line)[3] for line in sockets("lt")]
        assert listening == [f"127.0.0.1:{edge_local}"]
        dialled = poll(lambda: [line for line in sockets("t") if f"127.0.0.1:{tls_port}" in re.split(r"\s+", line)[4]]
                       or None, timeout=15)
        assert dialled, "the edge router never connected to the cloud router"
