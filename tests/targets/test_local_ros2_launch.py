"""A ROS 2 ``launch:`` node on the local target's native runtime: its workspace built with colcon, its
install/ overlay sourced, ``ros2 launch PKG FILE`` run, and its topic crossing to the robot's side.

colcon and ``ros2 launch`` are the stand-ins of tests.support.ros2 (no ROS 2 is packaged for this
Debian); the launch file is a plain script that runs the node, a zenoh-ros2-sdk publisher
(tests.net.zenoh.ros2node). The stand-in ``ros2 launch`` finds the package only through the
overlay colcon left, so the topic arriving shows the build and the overlay as well as the launch.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.procs import free_port
from tests.conftest import REPO
from tests.net.zenoh.lab import ZenohLab
from tests.support.ros2 import standin_ros2

pytest.importorskip("zenoh_ros2_sdk", reason="needs zenoh-ros2-sdk (pip install zenoh-ros2-sdk)")

LAUNCH = """#!/bin/bash
exec {python} -m tests.net.zenoh.ros2node "${{FOGIAC_ZENOH_ROUTER##*:}}" {out} --sub /camera=String \\
    --pub /detections=String
"""


def test_a_ros2_launch_node_is_built_with_colcon_and_run_by_ros2_launch(tmp_path: Path, _state_dir: Path,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PATH", f"{standin_ros2(tmp_path / 'ros2')}:{os.environ['PATH']}")
    cloud_out = tmp_path / "cloud.jsonl"
    pkg = tmp_path / "ws" / "src" / "fogdetect"
    (pkg / "launch").mkdir(parents=True)
    (pkg / "package.xml").write_text("<package format=\"3\"><name>fogdetect</name></package>\n")
    (pkg / "launch" / "detect.launch.py").write_text(LAUNCH.format(python=sys.executable, out=cloud_out))
    (pkg / "launch" / "detect.launch.py").chmod(0o755)
    edge_port = free_port()
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(f"""name: ros2-launch
ros: {{distro: jazzy}}
cloud: {{provider: local, runtime: native}}
edge: {{zenoh_router: "tcp/127.0.0.1:{edge_port}"}}
nodes:
  - name: detector
    machine: t3.micro
    launch: {{package: fogdetect, file: detect.launch.py, workspace: ws}}
    env: {{PYTHONPATH: "{REPO}", RUST_LOG: error}}
    topics: {{in: [/camera], out: [/detections]}}
""")
    runner = CliRunner()
    try:
        up = runner.invoke(app, ["up", str(manifest), "--yes"])
        assert up.exit_code == 0, up.output
        with ZenohLab(tmp_path) as lab:
            robot = lab.node("robot", edge_port, pub=("/camera=String",), sub=("/detections=String",))
            lab.wait_received(robot, "/detections", count=3)
            lab.wait_received(cloud_out, "/camera", count=3)
        again = runner.invoke(app, ["up", str(manifest), "--yes"])
        assert again.exit_code == 0 and "no changes" in again.output, again.output
    finally:
        down = runner.invoke(app, ["down", str(manifest), "--yes"])
    assert down.exit_code == 0, down.output
    assert "nothing left" in down.output
