"""Every shipped example validates and plans; every one the ``local`` target can run answers a robot.

Offline, for each ``examples/*.yaml``: ``validate`` and ``plan`` on its own target (AWS, planned
without touching it) and on ``local``. Then, for the examples the local target can run, the whole
cycle with real parts, as a user would try one before paying for it: ``up --target local --yes
--start-edge-master`` (the edge roscore on a free port, the one change made to the example), one
request from a robot-side client through the relay, ``status --json`` counting the relayed
topics, and ``down`` leaving no process and no sandbox.

An example added to examples/ must be listed in ``RUNS`` or ``NOT_LOCAL`` (with why), so that
"every example" stays true.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.procs import free_port
from tests.conftest import EXAMPLES, REPO
from tests.support.podman import podman_missing
from tests.support.procs import alive, started_pids
from tests.support.ros import ros_missing

BASE = "docker.io/library/ros:noetic-ros-core"
FILES = sorted(p.name for p in EXAMPLES.glob("*.yaml"))

# What the local target cannot run, and why (a placeholder image of the user's own, for one).
NOT_LOCAL = {
    "ros2-zenoh.yaml": "its node is ghcr.io/example/detector:jazzy, a placeholder for the user's own ROS 2 image "
                       "(tests/targets/test_local_ros2.py runs the same Zenoh path with a stand-in node)",
}


def _robot_env(edge_port: int) -> dict[str, str]:
    return {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{edge_port}", "ROS_HOSTNAME": "127.0.0.1",
            "PYTHONPATH": str(REPO)}


LISTENER = """\
import sys
import rospy
from std_msgs.msg import String
rospy.init_node("robot_listener", anonymous=True, disable_signals=True)
print(rospy.wait_for_message("/chatter", String, timeout=90).data, flush=True)
rospy.Subscriber("/chatter", String, lambda msg: None)
sys.stdin.read()  # stays subscribed until the test closes its stdin
"""


def _hear_chatter(edge_port: int, tmp_path: Path) -> Callable[[], None]:
    # A typed subscriber: the relay carries a discovered topic while the robot's side asks for it
    # (`rostopic echo` asks for nothing until the topic is published on its own master), so the
    # listener stays subscribed until status has counted it.
    listener = subprocess.Popen([sys.executable, "-c", LISTENER], env=_robot_env(edge_port), stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    assert listener.stdout is not None and listener.stdin is not None

    def leave() -> None:
        listener.communicate(timeout=30)  # closes stdin: the listener ends

    heard = listener.stdout.readline().strip()  # the listener gives up by itself after 90 s
    if heard != "hello from the cloud":
        _, err = listener.communicate(timeout=30)
        pytest.fail(f"the robot heard {heard!r} on /chatter; its stderr: {err[-2000:]}")
    return leave


def _plan_a_path(edge_port: int, tmp_path: Path) -> None:
    from tests.targets.test_local import ask_planner

    answer = ask_planner(edge_port, cwd=tmp_path)
    assert answer["solved"] and answer["poses"] >= 2 and answer["free"], answer
    assert 0 < answer["compute_time_s"] < answer["round_trip_s"]


def _ask_a_grasp(edge_port: int, tmp_path: Path) -> None:
    from tests.provision.test_plain_user import ask_grasp

    grasp = ask_grasp(edge_port, cwd=tmp_path)
    assert "error" not in grasp and 0.0 <= grasp["quality"] <= 1.0, grasp


SLAM_FRAMES = 24


def _play_slam(edge_port: int, tmp_path: Path) -> None:
    """A short rendered sequence at half resolution, each frame sent once the last was answered; poses come back."""
    from workloads.slam.camera import Intrinsics
    from workloads.slam.render import render_sequence

    seq = tmp_path / "desk"
    render_sequence(seq, kind="desk", frames=SLAM_FRAMES, intrinsics=Intrinsics.fr1().scaled(0.5))
    played = subprocess.run([sys.executable, "-m", "workloads.slam", "play", str(seq), "--lockstep", "--wait", "90",
                             "--json"], env=_robot_env(edge_port), capture_output=True, text=True, timeout=180,
                            cwd=tmp_path)
    assert played.returncode == 0, played.stderr[-3000:]
    report = json.loads(played.stdout.strip().splitlines()[-1])
    assert report["frames"] == SLAM_FRAMES
    assert report["poses"] >= SLAM_FRAMES - 2, report  # in lockstep no frame is dropped for a busy node
    assert report["ate_rmse_m"] is not None and report["ate_rmse_m"] <= 0.05, report
    assert report["compute_time_messages"] >= SLAM_FRAMES and report["network_ms_median"] is not None, report


def _roscore() -> str | None:
    return ros_missing("sensor_msgs.msg", "geometry_msgs.msg")


def _podman() -> str | None:
    return _roscore() or podman_missing(BASE, "the test base image")


class Run:
    """How one example runs locally: what it needs, the robot's request, the topics the relay must count.

    ``ask`` may return a callable that ends a robot-side client kept running until status was read."""

    def __init__(self, ask: Callable[[int, Path], Callable[[], None] | None], topics: set[str], *,
                 missing: Callable[[], str | None] = _roscore, runtime: str = "") -> None:
        self.ask, self.topics, self.missing, self.runtime = ask, topics, missing, runtime


RUNS = {
    # An image node: the local target runs it in a container (podman) beside its sandbox's master.
    "minimal.yaml": Run(_hear_chatter, {"/chatter"}, missing=_podman, runtime="container"),
    "motion-planning.yaml": Run(_plan_a_path, {"/motion_planning/request", "/motion_planning/path"}),
    # Topics "auto": the path crosses while the client subscribes to it; the node's subscription stays.
    "proxy.yaml": Run(_plan_a_path, {"/motion_planning/request"}),
    "grasp-planning.yaml": Run(_ask_a_grasp, {"/depth/image", "/grasp"}),
    "slam.yaml": Run(_play_slam, {"/camera/rgb/image_color", "/camera/depth/image", "/slam/pose"}),
}


def test_every_example_is_either_run_locally_or_says_why_not() -> None:
    assert sorted([*RUNS, *NOT_LOCAL]) == FILES
    assert not set(RUNS) & set(NOT_LOCAL)


@pytest.mark.parametrize("name", FILES)
def test_example_validates_and_plans_offline(name: str) -> None:
    runner = CliRunner()
    path = str(EXAMPLES / name)
    checked = runner.invoke(app, ["validate", path])
    assert checked.exit_code == 0, checked.output
    assert "registry.example.com" not in (EXAMPLES / name).read_text()
    for target in ([], ["--target", "local"]):
        planned = runner.invoke(app, ["plan", path, *target, "--json"])
        assert planned.exit_code == 0, planned.output
        changes = json.loads(planned.stdout)["changes"]  # stdout: placeholder warnings go to stderr
        assert changes["add"] > 0 or changes["hosts"]["added"], (target, changes)


def _local_manifest(name: str, tmp_path: Path, *, edge_port: int, runtime: str) -> tuple[Path, str]:
    """The example as shipped but for the edge master's port (and a runtime where it needs one named)."""
    doc: dict[str, Any] = yaml.safe_load((EXAMPLES / name).read_text())
    doc.setdefault("edge", {})["ros_master"] = f"http://127.0.0.1:{edge_port}"
    if runtime:
        doc["cloud"]["runtime"] = runtime
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path, doc["name"]


def _params() -> list[Any]:
    params = []
    for name in FILES:
        if name in NOT_LOCAL:
            params.append(pytest.param(name, marks=pytest.mark.skip(reason=f"{name}: {NOT_LOCAL[name]}")))
            continue
        why = RUNS[name].missing() if name in RUNS else None
        marks = [pytest.mark.ros] + ([pytest.mark.skip(reason=why)] if why else [])
        params.append(pytest.param(name, marks=marks))
    return params


@pytest.mark.parametrize("name", _params())
def test_example_goes_up_answers_a_robot_and_comes_down(name: str, tmp_path: Path, _state_dir: Path) -> None:
    run = RUNS[name]
    edge_port = free_port()
    manifest, stack = _local_manifest(name, tmp_path, edge_port=edge_port, runtime=run.runtime)
    runner = CliRunner()
    pids: list[int] = []
    leave: Callable[[], None] | None = None

    def status() -> dict:
        shown = runner.invoke(app, ["status", str(manifest), "--target", "local", "--json"])
        assert shown.exit_code == 0, shown.output
        return json.loads(shown.output)

    try:
        up = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes", "--start-edge-master"])
        assert up.exit_code == 0, up.output
        pids = started_pids(_state_dir)
        assert pids, "up started no supervised process"

        leave = run.ask(edge_port, tmp_path)

        deadline = time.monotonic() + 15  # the relay rewrites its stats file once a second
        doc = status()
        while not run.topics <= {t["topic"] for t in doc["relays"][0].get("topics", []) if t["msgs"]}:
            assert time.monotonic() < deadline, f"relay stats never counted {sorted(run.topics)}: {doc}"
            time.sleep(0.5)
            doc = status()
        (relay,) = doc["relays"]
        assert relay["connected"] is True
        assert all(node["running"] for host in doc["hosts"] for node in host["nodes"]), doc["hosts"]
        if name == "slam.yaml":  # the camera's throughput and latency through the relay, and the answers'
            # One-way latency is measured where a message lands: the poses' here on the edge, the images'
            # on the cloud end, which reports it back over the link each second.
            def topics() -> dict[str, dict]:
                return {t["topic"]: t for t in status()["relays"][0]["topics"]}

            deadline = time.monotonic() + 15
            while topics()["/camera/rgb/image_color"]["latency_ms"] is None:
                assert time.monotonic() < deadline, f"no latency for the images: {topics()}"
                time.sleep(0.5)
            seen = topics()
            image = seen["/camera/rgb/image_color"]
            assert image["msgs"] >= SLAM_FRAMES and image["compression"] == "lz4", image
            assert image["bytes"] >= image["msgs"] * 320 * 240 * 3, image  # bgr8 frames, counted uncompressed
            assert image["latency_ms"] >= 0 and seen["/slam/pose"]["latency_ms"] is not None, seen
    finally:
        if leave is not None:
            leave()
        down = runner.invoke(app, ["down", str(manifest), "--target", "local", "--yes"])
    assert down.exit_code == 0, down.output
    assert "nothing left" in down.output
    left = [pid for pid in pids if alive(pid)]
    assert left == [], [Path(f"/proc/{p}/cmdline").read_bytes() for p in left]
    assert not (_state_dir / f"{stack}-dev" / "local").exists()
