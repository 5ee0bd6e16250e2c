"""The ROS node against a real roscore: a depth image and CameraInfo in, a PoseStamped out."""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import xmlrpc.client
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[3]
CLIENT = Path(__file__).with_name("grasp_ros_client.py")


def _ros_missing() -> str | None:
    if shutil.which("roscore") is None:
        return "roscore not installed (apt-get install ros-core)"
    probe = subprocess.run(
        [sys.executable, "-c", "import rospy, sensor_msgs.msg, geometry_msgs.msg, std_msgs.msg"], capture_output=True
    )
    if probe.returncode:
        return "rospy or its message packages are not importable (apt-get install python3-rospy python3-sensor-msgs python3-geometry-msgs)"
    return None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _stop(proc: subprocess.Popen) -> None:
    for sig in (signal.SIGINT, signal.SIGKILL):
        if proc.poll() is not None:
            break
        try:
            os.killpg(proc.pid, sig)
            proc.wait(timeout=10)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            pass
    try:
        os.killpg(proc.pid, signal.SIGKILL)  # anything the group left behind
    except ProcessLookupError:
        pass


@pytest.fixture
def ros_env(tmp_path: Path) -> Iterator[dict[str, str]]:
    reason = _ros_missing()
    if reason:
        pytest.skip(reason)
    port = _free_port()
    env = {
        **os.environ,
        "ROS_MASTER_URI": f"http://127.0.0.1:{port}",
        "ROS_HOSTNAME": "127.0.0.1",
        "ROS_HOME": str(tmp_path / "ros"),
        "ROS_LOG_DIR": str(tmp_path / "ros" / "log"),
        "PYTHONPATH": os.pathsep.join(p for p in (str(REPO), os.environ.get("PYTHONPATH", "")) if p),
    }
    core = subprocess.Popen(
        ["roscore", "-p", str(port)], env=env, start_new_session=True,
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    try:
        master = xmlrpc.client.ServerProxy(env["ROS_MASTER_URI"])
        deadline = time.monotonic() + 30
        while True:
            try:
                master.getSystemState("/test")
                break
            except OSError:
                if time.monotonic() > deadline or core.poll() is not None:
                    pytest.fail("roscore did not come up within 30 s")
                time.sleep(0.1)
        yield env
    finally:
        _stop(core)


def test_node_answers_a_depth_image_with_a_grasp_pose(ros_env: dict[str, str], tmp_path: Path) -> None:
    from workloads.grasp_planning.data import TEST_SEED, bench_scene
    from workloads.grasp_planning.planner import GraspPlanner

    s = bench_scene(TEST_SEED + 7, height=240, width=320)
    depth_path = tmp_path / "depth.npy"
    np.save(depth_path, s.depth)
    node = subprocess.Popen(
        [sys.executable, "-m", "workloads.grasp_planning", "node", "_device:=cpu", "_threads:=1"],
        cwd=REPO, env=ros_env, start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
    )
    try:
        intr = s.intr
        client = subprocess.run(
            [sys.executable, str(CLIENT), str(depth_path), str(intr.fx), str(intr.fy), str(intr.cx), str(intr.cy),
             "90", "32FC1", "16UC1"],
            cwd=REPO, env=ros_env, capture_output=True, text=True, timeout=150, start_new_session=True,
        )
    finally:
        _stop(node)
    log = node.stdout.read().decode(errors="replace") if node.stdout else ""
    answers = [json.loads(line) for line in client.stdout.splitlines() if line.startswith("{")]
    assert client.returncode == 0, client.stderr[-2000:] + log[-2000:]
    assert [a["encoding"] for a in answers] == ["32FC1", "16UC1"], client.stdout + log[-2000:]
    expected = GraspPlanner.load(device="cpu").plan(s.depth, s.intr)
    for a in answers:
        assert "error" not in a, a
        # the header is the image's own: the client can match and time its request
        assert a["frame_id"] == "camera_depth_optical_frame"
        assert a["stamp"][0] > 1000 and a["stamp"][1] == 500
        assert a["position"] == pytest.approx(list(expected.pose.position), abs=2e-3)
        assert a["orientation"] == pytest.approx(list(expected.pose.orientation), abs=1e-6)
        assert math.isclose(sum(c * c for c in a["orientation"]), 1.0, rel_tol=1e-9)
        assert 0.0 <= a["quality"] <= 1.0
        assert a["compute_time"] > 0.0
