"""A ROS 2 manifest deployed on the local target end to end: fogiac's Zenoh routers carry it.

``up`` starts a Zenoh router in the sandbox (mutual TLS for the edge, loopback for its nodes,
access control from the manifest) and the sandbox's node, a zenoh-ros2-sdk stand-in run as a
bare ``command`` with the router's endpoint from its environment; on the edge it starts the edge
router (dialing out) and the monitor. A robot-side stand-in on the edge router exchanges the
listed topics both ways; the unlisted ones do not cross; ``status`` shows the link and the
figures; ``down`` leaves no process. With autostop on, a sandbox whose edge router goes away
stops by itself, and ``status`` says so.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.manifest.schema import load_manifest
from fogiac.lifecycle.edge import stop_edge
from fogiac.plan.compile import compile_plan
from fogiac.procs import free_port
from tests.conftest import REPO
from tests.net.zenoh.lab import ZenohLab, read_events
from tests.support.procs import alive, started_pids
from tests.support.ros2 import standin_ros2

pytest.importorskip("zenoh_ros2_sdk", reason="needs zenoh-ros2-sdk (pip install zenoh-ros2-sdk)")


@pytest.fixture(autouse=True)
def _ros2_on_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The sandbox is this machine: ROS 2 (a stand-in, see tests.support.ros2) in its login environment."""
    monkeypatch.setenv("PATH", f"{standin_ros2(tmp_path / 'ros2')}:{os.environ['PATH']}")

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


IDLER = """\
name: ros2-idler
ros: {{distro: jazzy}}
cloud: {{provider: local, runtime: native, autostop: {{idle_minutes: 0.15, action: stop}}}}
edge: {{zenoh_router: "tcp/127.0.0.1:{edge_port}"}}
nodes:
  - name: detector
    machine: t3.micro
    command: [bash, -c, 'exec {python} -m tests.net.zenoh.ros2node "${{FOGIAC_ZENOH_ROUTER##*:}}" {out}
              --pub /detections=String']
    env: {{PYTHONPATH: "{repo}", RUST_LOG: error}}
    topics: {{out: [/detections]}}
"""


def test_a_ros2_sandbox_whose_edge_router_leaves_stops_by_itself(tmp_path: Path, _state_dir: Path) -> None:
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(IDLER.format(edge_port=free_port(), python=sys.executable, out=tmp_path / "cloud.jsonl",
                                     repo=REPO))
    plan = compile_plan(load_manifest(manifest))
    assert plan.autostop is not None and plan.autostop.idle_s == 9.0
    runner = CliRunner()

    def host() -> dict:
        shown = runner.invoke(app, ["status", str(manifest), "--json"])
        assert shown.exit_code == 0, shown.output
        (only,) = json.loads(shown.output)["hosts"]
        return only

    try:
        up = runner.invoke(app, ["up", str(manifest), "--yes"])
        assert up.exit_code == 0, up.output
        deadline = time.monotonic() + 15  # the router tells its watchdog, within a second, that the edge is linked
        seen = host()
        while (seen["autostop"] or {}).get("idle_since") is not None or not seen["autostop"]:
            assert time.monotonic() < deadline, f"the watchdog never saw the edge router: {seen}"
            time.sleep(0.3)
            seen = host()
        assert seen["nodes"][0]["running"] is True

        stop_edge(plan)  # the robot's side goes away: its router and monitor stop
        deadline = time.monotonic() + 60
        while not (seen["autostop"] or {}).get("stopped_at"):
            assert time.monotonic() < deadline, f"the sandbox never stopped: {seen}"
            time.sleep(0.5)
            seen = host()
        assert seen["autostop"]["idle_since"] is not None
        assert seen["nodes"][0]["running"] is False
        human = runner.invoke(app, ["status", str(manifest)])
        assert "detector: stopped by autostop at" in human.output, human.output
    finally:
        down = runner.invoke(app, ["down", str(manifest), "--yes"])
    assert down.exit_code == 0, down.output
