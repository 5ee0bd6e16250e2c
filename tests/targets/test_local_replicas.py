"""Replicas on ``local`` (issue 24): two sandboxes for one node, and a replica whose host died comes back on
the next ``fogiac up`` while the other keeps running, untouched (its node the same process throughout).

Real parts: fogiac's own up/status/down, the supervisor, a real roscore per sandbox and the edge's.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.procs import descendants, free_port
from tests.support.procs import alive, alive_pids, started_pids

pytestmark = [
    pytest.mark.ros,
    pytest.mark.skipif(shutil.which("roscore") is None, reason="needs Debian's ros-core (roscore)"),
]


def _child(sandbox: Path, node: str) -> int:
    """The pid of the node's process, as the sandbox's supervisor recorded it."""
    return int((sandbox / "run" / f"node-{node}.child").read_text().split()[0])


def test_a_dead_replica_is_replaced_by_up_and_the_other_is_not_touched(tmp_path: Path, _state_dir: Path) -> None:
    edge_port = free_port()
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(f"""name: reps
cloud: {{provider: local}}
edge: {{ros_master: "http://127.0.0.1:{edge_port}"}}
nodes:
  - name: planner
    machine: t3.micro
    command: [sleep, "3600"]
    replicas: 2
    topics: {{in: [/plan/request], out: [/plan/path]}}
    message_types: {{/plan/path: geometry_msgs/PoseArray}}
""")
    runner = CliRunner()
    sandboxes = _state_dir / "reps-dev" / "local"
    r1, r2 = sandboxes / "planner-r1", sandboxes / "planner-r2"
    try:
        up = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes", "--start-edge-master"])
        assert up.exit_code == 0, up.output
        assert r1.is_dir() and r2.is_dir()  # a sandbox each: own folder, own master and relay ports
        first, second = _child(r1, "planner"), _child(r2, "planner")
        assert first != second and alive(first) and alive(second)
        status = runner.invoke(app, ["status", str(manifest), "--target", "local", "--json"])
        assert status.exit_code == 0, status.output
        hosts = {h["host"]: h for h in json.loads(status.output)["hosts"]}
        assert set(hosts) == {"planner-r1", "planner-r2"}
        assert all(h["nodes"][0]["running"] is True for h in hosts.values())

        # replica 2's host dies: every process it ran (roscore's rosmaster and rosout too) is killed and its
        # disk is gone
        recorded = [pid for pid in started_pids(r2) if alive(pid)]
        assert recorded
        doomed = recorded + [child for pid in recorded for child in descendants(pid)]
        for pid in doomed:
            with contextlib.suppress(ProcessLookupError):  # a child may go with its supervisor
                os.kill(pid, signal.SIGKILL)
        shutil.rmtree(r2)
        assert alive(first)

        again = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes"])
        assert again.exit_code == 0, again.output
        assert r2.is_dir() and alive(_child(r2, "planner")) and _child(r2, "planner") != second
        assert _child(r1, "planner") == first and alive(first)  # the healthy replica ran on, untouched
        status = runner.invoke(app, ["status", str(manifest), "--target", "local", "--json"])
        hosts = {h["host"]: h for h in json.loads(status.output)["hosts"]}
        assert all(h["nodes"][0]["running"] is True for h in hosts.values())
    finally:
        down = runner.invoke(app, ["down", str(manifest), "--target", "local", "--yes"])
    assert down.exit_code == 0, down.output
    assert alive_pids(_state_dir) == []
    assert _naming(_state_dir) == []  # nothing left that runs from the stack's folders (a master's children too)
    assert not sandboxes.exists()


def _naming(folder: Path) -> list[str]:
    """The command lines of live processes that name ``folder``."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            with contextlib.suppress(OSError):
                line = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
                if str(folder) in line:
                    found.append(line)
    return found
