"""The ROS node against a real roscore, fed by the robot-side player in its own process."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.conftest import REPO
from tests.support.ros import ros_missing, roscore, stop_group
from tests.workloads.slam.conftest import FEATURES

pytestmark = pytest.mark.ros

FRAMES = 60


@pytest.fixture
def node_env(tmp_path: Path) -> Iterator[dict[str, str]]:
    """A roscore on a free port and the SLAM node (2 cores) attached to it."""
    reason = ros_missing("sensor_msgs.msg", "geometry_msgs.msg")
    if reason:
        pytest.skip(reason)
    with roscore(tmp_path, pythonpath=str(REPO)) as env:
        log = (tmp_path / "node.log").open("w")
        node = subprocess.Popen([sys.executable, "-m", "workloads.slam", "node", "_cores:=2", f"_features:={FEATURES}"],
                                cwd=REPO, env=env, start_new_session=True, stdout=log, stderr=subprocess.STDOUT)
        try:
            yield env
        finally:
            stop_group(node)


def test_robot_plays_a_sequence_and_gets_poses_and_the_map(node_env: dict[str, str], desk: Path) -> None:
    # 10 frames a second: the node keeps up on a busy 2-core machine, so nearly every frame gets a pose.
    result = subprocess.run([sys.executable, "-m", "workloads.slam", "play", str(desk), "--rate", "10",
                             "--max-frames", str(FRAMES), "--json"], cwd=REPO, env=node_env, capture_output=True,
                            text=True, timeout=240)
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert report["frames"] == FRAMES
    assert report["poses"] >= FRAMES // 2  # frames the node had to drop get no pose; most must
    assert report["compute_time_messages"] >= report["poses"]
    assert report["map_clouds"] >= 1 and report["map_points"] > 100
    # Poses come back with the images' stamps (the sequence's): they evaluate against its ground truth.
    assert report["ate_rmse_m"] is not None and report["ate_rmse_m"] <= 0.03
    assert report["round_trip_ms_median"] is not None
