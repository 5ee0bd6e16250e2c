"""ROS 2 nodes in containers on the local target, as every AWS host runs them: a real OCI engine (podman).

The node is a user's ``build:`` image over ``ros:jazzy-ros-core`` (here the stand-in that
``.ci/containers.sh`` builds: the Debian test base plus zenoh-ros2-sdk, since no ROS 2 image can
be pulled here). Its command names no router: it finds the sandbox's Zenoh router only from what
fogiac gives the container, ``RMW_IMPLEMENTATION=rmw_zenoh_cpp`` and ``ZENOH_CONFIG_OVERRIDE``, read
over rmw_zenoh's default session config as rmw_zenoh_cpp reads them. A robot-side stand-in on the
edge router exchanges the listed topics both ways; the unlisted ones cross in neither direction;
``down`` leaves no container. The official ROS images lack rmw_zenoh_cpp: a ``command`` node runs in
the plan's image when it has it (the stand-in answers ``ros2 pkg prefix rmw_zenoh_cpp``), and
fogiac layers ``ros-<distro>-rmw-zenoh-cpp`` over one that does not.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import time
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.procs import free_port
from tests.net.zenoh.lab import ZenohLab
from tests.support.podman import podman_missing

BASE = "docker.io/library/ros:jazzy-ros-core"
NODE = Path(__file__).resolve().parents[1] / "net" / "zenoh" / "ros2node.py"


_MISSING = podman_missing(BASE, "the ROS 2 stand-in image")
pytestmark = [pytest.mark.zenoh, pytest.mark.skipif(_MISSING is not None, reason=_MISSING or "")]
pytest.importorskip("zenoh_ros2_sdk", reason="needs zenoh-ros2-sdk (pip install zenoh-ros2-sdk) for the robot side")

# PORT 0: the node is told no router; it writes its events to its stdout (the service's log).
DOCKERFILE = """FROM ros:jazzy-ros-core
COPY ros2node.py /opt/ros2node.py
CMD ["python3", "/opt/ros2node.py", "0", "/dev/stdout", "--sub", "/camera=String", "--sub", "/leak=String", \
"--pub", "/detections=String", "--pub", "/secret=String"]
"""


def _events(log: Path) -> list[dict[str, Any]]:
    if not log.exists():
        return []
    return [json.loads(line) for line in log.read_text(errors="replace").splitlines() if line.startswith('{"event"')]


def _received(log: Path, topic: str) -> int:
    return sum(1 for e in _events(log) if e["event"] == "received" and e["topic"] == topic)


def _containers(stack: str) -> list[str]:
    out = subprocess.run(["podman", "ps", "-a", "--filter", f"label=fogiac.stack={stack}", "--format",
                          "{{.Names}}"], capture_output=True, text=True, check=True).stdout
    return sorted(out.split())


def test_a_ros2_build_node_in_podman_finds_its_router_from_its_env_and_only_listed_topics_cross(
        tmp_path: Path, _state_dir: Path) -> None:
    context = tmp_path / "app"
    context.mkdir()
    (context / "Dockerfile").write_text(DOCKERFILE)
    shutil.copy2(NODE, context / "ros2node.py")
    edge_port = free_port()
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(f"""name: ros2-ctr
ros: {{distro: jazzy}}
cloud: {{provider: local, runtime: container}}
edge: {{zenoh_router: "tcp/127.0.0.1:{edge_port}"}}
nodes:
  - name: detector
    machine: t3.micro
    build: {{context: app}}
    env: {{RUST_LOG: error}}
    topics: {{in: [/camera], out: [/detections]}}
  - name: idle
    machine: t3.micro
    command: [sleep, "3600"]
    topics: {{out: [/idle]}}
""")
    runner = CliRunner()
    try:
        up = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes"])
        assert up.exit_code == 0, up.output
        assert _containers("ros2-ctr-dev") == ["fogiac-ros2-ctr-dev-detector", "fogiac-ros2-ctr-dev-idle"]
        idle_image = subprocess.run(["podman", "inspect", "--format", "{{.ImageName}}", "fogiac-ros2-ctr-dev-idle"],
                                    capture_output=True, text=True, check=True).stdout.strip()
        assert idle_image == BASE  # it has rmw_zenoh_cpp: nothing layered over it
        marker = _state_dir / "ros2-ctr-dev" / "local" / "idle" / "state" / "ros-image.sha256"
        assert marker.read_text().split()[1] == "ros:jazzy-ros-core"
        again = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes"])
        assert again.exit_code == 0 and "no changes" in again.output, again.output
        inspected = json.loads(subprocess.run(["podman", "inspect", "fogiac-ros2-ctr-dev-detector"],
                                              capture_output=True, text=True, check=True).stdout)[0]
        env = dict(e.split("=", 1) for e in inspected["Config"]["Env"])
        assert env["RMW_IMPLEMENTATION"] == "rmw_zenoh_cpp"
        assert env["ZENOH_CONFIG_OVERRIDE"].startswith('connect/endpoints=["tcp/127.0.0.1:')
        assert inspected["HostConfig"]["NetworkMode"] == "host"
        log = _state_dir / "ros2-ctr-dev" / "local" / "detector" / "run" / "node-detector.log"
        with ZenohLab(tmp_path) as lab:
            robot = lab.node("robot", edge_port, pub=("/camera=String", "/leak=String"),
                             sub=("/detections=String", "/secret=String"))
            lab.wait_received(robot, "/detections", count=3)
            deadline = time.monotonic() + 30
            while _received(log, "/camera") < 3:
                assert time.monotonic() < deadline, log.read_text()[-2000:] if log.exists() else "no log"
                time.sleep(0.3)
            time.sleep(1.0)  # the unlisted topics had as long as the listed ones, and more
            assert lab.received(robot, "/secret") == 0
            assert _received(log, "/leak") == 0
            sent = {e["topic"] for e in _events(log) if e["event"] == "sent"}
            assert {"/secret", "/detections"} <= sent  # the node did publish what was stopped
    finally:
        down = runner.invoke(app, ["down", str(manifest), "--target", "local", "--yes"])
    assert down.exit_code == 0, down.output
    assert "nothing left" in down.output
    assert _containers("ros2-ctr-dev") == []


HUMBLE = "docker.io/library/ros:humble-ros-core"


def test_a_ros_image_without_rmw_zenoh_gets_it_layered_on_and_a_failed_layer_is_one_line(
        tmp_path: Path, _state_dir: Path) -> None:
    """Here humble's image is the Debian base (ROS 1 only): fogiac builds ros-humble-rmw-zenoh-cpp over
    it, which Debian's archive does not have, so the build stops at that step, in one line."""
    if subprocess.run(["podman", "image", "exists", HUMBLE], capture_output=True).returncode == 0:
        pytest.skip(f"{HUMBLE} exists on this machine: the test would not know what it holds")
    subprocess.run(["podman", "tag", "docker.io/library/ros:noetic-ros-core", HUMBLE], check=True)
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(f"""name: ros2-bare
ros: {{distro: humble}}
cloud: {{provider: local, runtime: container}}
edge: {{zenoh_router: "tcp/127.0.0.1:{free_port()}"}}
nodes:
  - {{name: idle, machine: t3.micro, command: [sleep, "3600"], topics: {{out: [/idle]}}}}
""")
    runner = CliRunner()
    try:
        up = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes"])
        assert up.exit_code == 1, up.output
        (error,) = [line for line in up.output.splitlines() if line.startswith("error:")]
        log = _state_dir / "ros2-bare-dev" / "local" / "idle" / "build" / "ros-image.log"
        assert error.startswith("error: idle: node the ROS image (ros-humble-rmw-zenoh-cpp): image build failed "
                                "at STEP 2/2: RUN apt-get update && apt-get install -y --no-install-recommends "
                                "ros-humble-rmw-zenoh-cpp"), error
        assert f"; log: {log}" in error and "STEP 2/2: RUN apt-get update" in log.read_text()
        assert _containers("ros2-bare-dev") == []
    finally:
        runner.invoke(app, ["down", str(manifest), "--target", "local", "--yes"])
        # that name only: `podman untag IMAGE` alone would strip every name of the image, noetic's too
        subprocess.run(["podman", "untag", HUMBLE, HUMBLE], capture_output=True)
