"""A ROS 2 manifest deployed on the local target end to end: fogiac's Zenoh routers carry it.

``up`` starts a Zenoh router in the sandbox (mutual TLS for the edge, loopback for its nodes,
access control from the manifest) and the sandbox's node, a zenoh-ros2-sdk stand-in run as a
bare ``command`` with the router's endpoint from its environment; on the edge it starts the edge
router (dialing out) and the monitor. A robot-side stand-in on the edge router exchanges the
listed topics both ways; the unlisted ones do not cross; ``status`` shows the link and the
figures; ``down`` leaves no process.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.procs import free_port
from tests.conftest import REPO
from tests.net.zenoh.lab import ZenohLab, read_events
from tests.support.procs import alive, started_pids

pytest.importorskip("zenoh_ros2_sdk", reason="needs zenoh-ros2-sdk (pip install zenoh-ros2-sdk)")

MANIFEST = """\
name: ros2-local
ros: {{distro: jazzy}}
cloud: {{provider: local, runtime: native}}
edge: {{zenoh_router: "tcp/127.0.0.1:{edge_port}"}}
nodes:
  - name: detector
    machine: t3.micro
    command: [bash, -c, 'exec {python} -m tests.net.zenoh.ros2node "${{FOGIAC_ZENOH_ROUTER##*:}}" {out}
              --sub /camera=String --sub /leak=String --pub /detections=String --pub /secret=String']
    env: {{PYTHONPATH: "{repo}", RUST_LOG: error}}
    topics: {{in: [/camera], out: [/detections]}}
"""


def test_ros2_manifest_up_exchanges_listed_topics_only_and_down_stops_everything(tmp_path: Path,
                                                                                  _state_dir: Path) -> None:
    edge_port = free_port()
    cloud_out = tmp_path / "cloud.jsonl"
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(MANIFEST.format(edge_port=edge_port, python=sys.executable, out=cloud_out, repo=REPO))
    runner = CliRunner()
    pids: list[int] = []
    try:
        up = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes"])
        assert up.exit_code == 0, up.output
        assert "zenoh-bridge-ros2dds is not installed by fogiac" in up.output
        pids = started_pids(_state_dir)
        with ZenohLab(tmp_path) as lab:
            robot = lab.node("robot", edge_port, pub=("/camera=String", "/leak=String"),
                             sub=("/detections=String", "/secret=String"))
            lab.wait_received(robot, "/detections", count=3)
            lab.wait_received(cloud_out, "/camera", count=3)

            def status() -> dict:
                shown = runner.invoke(app, ["status", str(manifest), "--target", "local", "--json"])
                assert shown.exit_code == 0, shown.output
                return json.loads(shown.output)

            deadline = time.monotonic() + 15  # the edge router and monitor write their figures every second
            doc = status()
            while not (doc["relays"] and doc["relays"][0]["connected"]
                       and {t["topic"] for t in doc["relays"][0]["topics"] if t["msgs"]} == {"/camera", "/detections"}):
                assert time.monotonic() < deadline, doc
                time.sleep(0.5)
                doc = status()
            (link,) = doc["relays"]
            directions = {t["topic"]: t["direction"] for t in link["topics"]}
            assert directions == {"/camera": "in", "/detections": "out"}  # as the manifest says
            time.sleep(1.0)  # the unlisted topics had as long as the listed ones, and more
            assert lab.received(robot, "/secret") == 0
            assert lab.received(cloud_out, "/leak") == 0
            sent = {e["topic"] for e in read_events(cloud_out) if e["event"] == "sent"}
            assert {"/secret", "/detections"} <= sent  # the cloud did publish what was stopped
    finally:
        down = runner.invoke(app, ["down", str(manifest), "--target", "local", "--yes"])
    assert down.exit_code == 0, down.output
    assert "nothing left" in down.output
    assert pids
    left = [pid for pid in pids if alive(pid)]
    assert left == [], [Path(f"/proc/{p}/cmdline").read_bytes() for p in left]
    assert not (_state_dir / "ros2-local-dev" / "local").exists()
