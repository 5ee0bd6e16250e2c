"""The ROS node against a real roscore; the robot-side client runs in its own process."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from tests.workloads.motion_planning.mp_support import PROBLEMS, REPO

from tests.support.ros import ros_missing, roscore, stop_group
from workloads.motion_planning import Pose, load_problem, path_is_collision_free

pytestmark = pytest.mark.ros

ENDPOINTS_CLIENT = """
import json, math, rospy
from workloads.motion_planning.client import request_paths
from workloads.motion_planning.problem import Pose
rospy.init_node("mp_test_client", anonymous=True, disable_signals=True)
ends = {"easy": (Pose(-2.0, -1.0, 1.0), Pose(2.0, 1.0, -1.0, 0.0, 0.0, math.sin(0.5), math.cos(0.5)))}
print(json.dumps([t.as_dict() for t in request_paths(["easy"], timeout=60, endpoints=ends)]))
"""

SEEDED_CLIENT = """
import json, rospy
from workloads.motion_planning.client import request_paths
rospy.init_node("mp_test_client", anonymous=True, disable_signals=True)
timings = request_paths(["easy"], timeout=60, seeds={"easy": 42}) + request_paths(["easy;sed=1"], timeout=60)
print(json.dumps([t.as_dict() for t in timings]))
"""


@pytest.fixture
def node_env(tmp_path: Path) -> Iterator[dict[str, str]]:
    """A roscore on a free port and the planner node (2 cores) attached to it."""
    reason = ros_missing("geometry_msgs.msg")
    if reason:
        pytest.skip(reason)
    procs: list[subprocess.Popen] = []
    with roscore(tmp_path, pythonpath=str(REPO)) as env:
        try:
            log = (tmp_path / "node.log").open("w")
            procs.append(subprocess.Popen([sys.executable, "-m", "workloads.motion_planning", "node", "_cores:=2",
                                           f"_problem_dir:={PROBLEMS}", "_time_limit:=30"], cwd=REPO, env=env,
                                          start_new_session=True, stdout=log, stderr=subprocess.STDOUT))
            yield env
        finally:
            for proc in reversed(procs):
                stop_group(proc)


def _client(env: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, *args], cwd=REPO, env=env, capture_output=True, text=True, timeout=180)


def test_node_answers_with_a_collision_free_path(node_env: dict[str, str]) -> None:
    result = _client(node_env, "-m", "workloads.motion_planning", "client", "easy", "nosuchproblem", "--timeout", "60",
                     "--json")
    assert result.returncode == 1, result.stderr  # the unknown problem gets an empty path
    easy, unknown = json.loads(result.stdout)
    assert (easy["name"], easy["solved"], unknown["name"], unknown["solved"]) == ("easy", True, "nosuchproblem", False)
    assert easy["compute_time_s"] > 0 and easy["round_trip_s"] >= easy["compute_time_s"]
    problem = load_problem(PROBLEMS / "easy.cfg")
    path = [Pose(**p) for p in easy["path"]]
    assert path[0].as_dict() == pytest.approx(problem.start.as_dict(), abs=1e-6)
    assert path[-1].as_dict() == pytest.approx(problem.goal.as_dict(), abs=1e-6)
    assert path_is_collision_free(problem, path, resolution=0.01)


def test_request_brings_its_own_endpoints(node_env: dict[str, str]) -> None:
    result = _client(node_env, "-c", ENDPOINTS_CLIENT)
    assert result.returncode == 0, result.stderr
    (timing,) = json.loads(result.stdout)
    path = [Pose(**p) for p in timing["path"]]
    assert (path[0].x, path[0].y, path[0].z) == pytest.approx((-2.0, -1.0, 1.0), abs=1e-6)
    assert (path[-1].x, path[-1].y, path[-1].z) == pytest.approx((2.0, 1.0, -1.0), abs=1e-6)
    problem = load_problem(PROBLEMS / "easy.cfg").with_endpoints(path[0], path[-1])
    assert path_is_collision_free(problem, path, resolution=0.01)


def test_a_request_may_name_its_seed_and_a_bad_one_is_named(node_env: dict[str, str], tmp_path: Path) -> None:
    result = _client(node_env, "-c", SEEDED_CLIENT)
    assert result.returncode == 0, result.stderr
    seeded, bad = json.loads(result.stdout)
    assert (seeded["name"], seeded["solved"], bad["name"], bad["solved"]) == ("easy", True, "easy;sed=1", False)
    log = (tmp_path / "node.log").read_text()
    assert "request 'easy;sed=1': after ';' only 'seed=N' (N a whole number) is understood" in log, log
