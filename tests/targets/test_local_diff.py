"""``fogiac plan`` against what a real ``up`` on the local target deployed, and after ``down``."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.procs import free_port
from tests.conftest import EXAMPLES

pytestmark = [
    pytest.mark.ros,
    pytest.mark.skipif(shutil.which("roscore") is None, reason="needs Debian's ros-core (roscore)"),
]
runner = CliRunner()


def test_plan_diffs_against_the_deployed_stack(tmp_path: Path, _state_dir: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    home = tmp_path / "home"  # the operator's: the edge master's logs stay out of its ~/.ros (issue 26 item 23)
    home.mkdir()
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.delenv("ROS_HOME", raising=False)
    monkeypatch.delenv("ROS_LOG_DIR", raising=False)
    manifest = tmp_path / "fogiac.yaml"
    text = (EXAMPLES / "motion-planning.yaml").read_text().replace(
        "ros_master: http://localhost:11311", f"ros_master: http://127.0.0.1:{free_port()}")
    manifest.write_text(text)
    plan = ["plan", str(manifest), "--target", "local", "--detailed-exitcode"]
    assert runner.invoke(app, plan).exit_code == 2  # nothing deployed yet
    try:
        up = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes", "--start-edge-master"])
        assert up.exit_code == 0, up.output
        assert list((_state_dir / "motion-planning-dev" / "edge" / "ros" / "log").iterdir())
        assert not (home / ".ros").exists()
        same = runner.invoke(app, plan)
        assert same.exit_code == 0, same.output
        assert same.output.splitlines()[-1] == "No changes. Your infrastructure matches the configuration."

        manifest.write_text(text.replace("out: [/motion_planning/path", "out: [/cmd_vel, /motion_planning/path"))
        changed = runner.invoke(app, plan)
        assert changed.exit_code == 2, changed.output
        lines = [line.strip() for line in changed.output.splitlines()]
        assert "compared with what was applied to motion-planning-dev" in lines
        assert ("! actuation topic added cloud -> robot: /cmd_vel (host planner): what the cloud side publishes "
                "there moves the robot") in lines
        assert "+ /cmd_vel (cloud -> robot, host planner)" in lines
        assert lines[-1] == "Plan: 0 to add, 0 to change, 0 to destroy."  # the local target creates no resources

        # issue 35 item 19: a changed machine is a changed host, and the summary counts it
        manifest.write_text(text.replace("machine: c5.24xlarge", "machine: c5.18xlarge"))
        moved = runner.invoke(app, plan)
        assert moved.exit_code == 2, moved.output
        lines = [line.strip() for line in moved.output.splitlines()]
        assert "~ planner" in lines and "machine: c5.24xlarge -> c5.18xlarge" in lines
        assert lines[-1] == "Plan: 0 to add, 1 to change, 0 to destroy."
    finally:
        down = runner.invoke(app, ["down", str(manifest), "--target", "local", "--yes"])
    assert down.exit_code == 0, down.output
    assert not (_state_dir / "motion-planning-dev" / "applied.json").exists()
    assert not (_state_dir / "motion-planning-dev" / "edge").exists()  # its logs went with it
    assert runner.invoke(app, plan).exit_code == 2
