"""The ROS node against a real roscore: a depth image and CameraInfo in, a PoseStamped out."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from tests.support.ros import ros_missing, roscore, stop_group

REPO = Path(__file__).resolve().parents[3]
CLIENT = Path(__file__).with_name("grasp_ros_client.py")


@pytest.fixture
def ros_env(tmp_path: Path) -> Iterator[dict[str, str]]:
    reason = ros_missing("sensor_msgs.msg", "geometry_msgs.msg")
    if reason:
        pytest.skip(reason)
    with roscore(tmp_path, pythonpath=str(REPO)) as env:
        yield env


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
        stop_group(node)
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
