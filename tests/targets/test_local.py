"""The whole local cycle with real parts: up, a planning request through the relay, status, down.

A real edge roscore (started by fogiac, as in the demo), a sandbox with its own roscore, the real
motion-planning node and the real relay pair over mutual TLS on loopback. After ``down`` no
process fogiac started is alive and no sandbox is left.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.procs import free_port
from tests.conftest import EXAMPLES, REPO
from tests.support.procs import alive, started_pids

pytestmark = [
    pytest.mark.ros,
    pytest.mark.skipif(shutil.which("roscore") is None, reason="needs Debian's ros-core (roscore)"),
]

CLIENT = textwrap.dedent("""\
    import json, sys
    import rospy
    from workloads.motion_planning.client import request_paths
    from workloads.motion_planning.problem import load_problem
    from workloads.motion_planning.geometry import path_is_collision_free
    from workloads.motion_planning.node import DEFAULT_PROBLEM_DIR
    rospy.init_node("robot_client", anonymous=True, disable_signals=True)
    (timing,) = request_paths(["easy"], timeout=120, connect_timeout=90)
    problem = load_problem(DEFAULT_PROBLEM_DIR / "easy.cfg")
    print(json.dumps({"solved": timing.solved, "poses": len(timing.path),
                      "free": path_is_collision_free(problem, list(timing.path), resolution=0.01),
                      "round_trip_s": timing.round_trip_s, "compute_time_s": timing.compute_time_s}))
""")


def ask_planner(edge_port: int, *, cwd: Path) -> dict:
    """The robot's side: one planning request through the edge master at ``edge_port``; the client's answer."""
    env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{edge_port}", "ROS_HOSTNAME": "127.0.0.1",
           "PYTHONPATH": str(REPO)}
    result = subprocess.run([sys.executable, "-c", CLIENT], env=env, capture_output=True, text=True,
                            timeout=240, cwd=cwd)
    assert result.returncode == 0, result.stderr[-3000:]
    return json.loads(result.stdout.strip().splitlines()[-1])


def test_local_up_request_status_down(tmp_path: Path, _state_dir: Path) -> None:
    edge_port = free_port()
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text((EXAMPLES / "motion-planning.yaml").read_text().replace(
        "ros_master: http://localhost:11311", f"ros_master: http://127.0.0.1:{edge_port}"))
    runner = CliRunner()
    try:
        up = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes", "--start-edge-master"])
        assert up.exit_code == 0, up.output
        assert "planner" in up.output
        pids = started_pids(_state_dir)
        assert pids, "up started no supervised process"

        answer = ask_planner(edge_port, cwd=tmp_path)
        assert answer["solved"] and answer["poses"] >= 2 and answer["free"], answer
        assert 0 < answer["compute_time_s"] < answer["round_trip_s"]

        def counts() -> tuple[dict, dict]:
            status = runner.invoke(app, ["status", str(manifest), "--target", "local", "--json"])
            assert status.exit_code == 0, status.output
            doc = json.loads(status.output)
            (relay,) = doc["relays"]
            return doc, {t["topic"]: t["msgs"] for t in relay.get("topics", [])}

        deadline = time.monotonic() + 15  # the relay rewrites its stats file once a second
        doc, msgs = counts()
        while not (msgs.get("/motion_planning/request") and msgs.get("/motion_planning/path")):
            assert time.monotonic() < deadline, f"relay stats never counted the request: {doc}"
            time.sleep(0.5)
            doc, msgs = counts()
        (host,) = doc["hosts"]
        assert host["host"] == "planner" and host["nodes"][0]["running"] is True
        assert doc["relays"][0]["connected"] is True
    finally:
        down = runner.invoke(app, ["down", str(manifest), "--target", "local", "--yes"])
    assert down.exit_code == 0, down.output
    assert "nothing left" in down.output
    assert [pid for pid in pids if alive(pid)] == []
    sandboxes = _state_dir / "motion-planning-dev" / "local"
    assert not sandboxes.exists()  # no sandbox and no ports.json: down forgets what up chose
