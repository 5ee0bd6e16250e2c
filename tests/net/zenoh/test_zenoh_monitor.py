"""``/fogros/latency`` and ``/fogros/throughput`` for ROS 2, live: fogiac's routers, the edge monitor, and a
ROS 2 subscriber stood in by zenoh-ros2-sdk that decodes them as ``std_msgs/msg/String``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fogiac.net.zenoh.monitor import data_key, string_cdr
from fogiac.procs import poll
from tests.net.zenoh.lab import IN_TOPICS, OUT_TOPICS, ZenohLab, free_ports, read_events, route

pytest.importorskip("zenoh", reason="needs eclipse-zenoh (pip install 'fogiac[ros2]')")
pytest.importorskip("zenoh_ros2_sdk", reason="needs zenoh-ros2-sdk (pip install 'fogiac[ros2]')")


def test_a_string_is_cdr_with_its_length_and_nul_under_rmw_zenohs_key() -> None:
    assert string_cdr("hi") == b"\x00\x01\x00\x00" + b"\x03\x00\x00\x00" + b"hi\x00"
    assert data_key("/fogros/latency", domain=7).startswith("7/fogros/latency/std_msgs::msg::dds_::String_/RIHS01_")


def _figures(out: Path, topic: str) -> list[dict]:
    return [json.loads(e["text"]) for e in read_events(out) if e["event"] == "received" and e["topic"] == topic]


@pytest.mark.zenoh
def test_a_ros2_subscriber_on_the_robot_receives_plausible_figures(tmp_path: Path) -> None:
    with ZenohLab(tmp_path) as lab:
        tls_port, cloud_local, edge_local = free_ports(3)
        lab.router("cloud-router", lab.cloud_config(route(tls_port), local_port=cloud_local))
        lab.router("edge-router", lab.edge_config([("127.0.0.1", tls_port)], local_port=edge_local))
        lab.node("cloud-node", cloud_local, pub=("/result=String",))  # every 100 ms, from the cloud
        lab.node("robot-pub", edge_local, pub=("/chatter_in=String",))  # every 100 ms, from the robot
        lab.monitor(edge_local, to_edge=OUT_TOPICS, to_cloud=IN_TOPICS)
        robot = lab.node("robot", edge_local, sub=("/fogros/latency=String", "/fogros/throughput=String"))

        def steady() -> bool:  # a figure from a period in which /result flowed the whole time
            return any(f["topics"]["/result"]["msgs_per_s"] >= 5 for f in _figures(robot, "/fogros/throughput"))

        assert lab.wait_received(robot, "/fogros/latency", count=3)
        assert lab.wait_received(robot, "/fogros/throughput", count=3)
        assert poll(lambda: steady() or None, timeout=30), _figures(robot, "/fogros/throughput")
        throughput = [f for f in _figures(robot, "/fogros/throughput") if f["topics"]["/result"]["msgs_per_s"] >= 5][-1]
        assert throughput["role"] == "edge"
        assert set(throughput["topics"]) == set(IN_TOPICS + OUT_TOPICS)
        result, chatter = throughput["topics"]["/result"], throughput["topics"]["/chatter_in"]
        assert result["direction"] == "in" and chatter["direction"] == "out"
        assert 5 <= result["msgs_per_s"] <= 20  # published at 10 Hz
        assert result["bytes_per_s"] > 50 * result["msgs_per_s"]  # each one is a 64-character string and more
        assert chatter["msgs"] > 0 and throughput["topics"]["/overlay"]["msgs"] == 0  # nobody publishes /overlay

        latency = [f["topics"]["/result"] for f in _figures(robot, "/fogros/latency")]
        measured = [t for t in latency if t["median_ms"] is not None]
        assert measured, latency
        assert all(0 <= t["median_ms"] <= t["p99_ms"] < 10_000 for t in measured)  # ms on one machine, not ns
        assert all(f["topics"]["/chatter_in"]["median_ms"] is None for f in _figures(robot, "/fogros/latency"))
