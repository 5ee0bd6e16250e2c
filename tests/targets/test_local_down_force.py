"""``down --force`` with another manifest of the same stack removes every host the record names (issue 26 item 15).

Two files with the same ``name:`` make one stack. ``up`` of the first started its hosts; ``down --force``
of the second stopped only the second's hosts and left the first's running (and its sandbox on disk).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.procs import free_port
from tests.support.procs import alive_pids, started_pids

pytestmark = [
    pytest.mark.ros,
    pytest.mark.skipif(shutil.which("roscore") is None, reason="needs Debian's ros-core (roscore)"),
]
runner = CliRunner()
MANIFEST = """name: twofiles
cloud: {{provider: local, runtime: native}}
edge: {{ros_master: 'http://127.0.0.1:{port}'}}
nodes:
  - {{name: {node}, machine: t3.small, command: [sleep, '600']}}
"""


def test_down_force_with_another_manifest_stops_the_first_ones_hosts(tmp_path: Path, _state_dir: Path) -> None:
    port = free_port()
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    first, second = tmp_path / "a" / "fogiac.yaml", tmp_path / "b" / "fogiac.yaml"
    first.write_text(MANIFEST.format(port=port, node="sleeper"))
    second.write_text(MANIFEST.format(port=port, node="other"))
    try:
        up = runner.invoke(app, ["up", str(first), "--yes", "--start-edge-master"])
        assert up.exit_code == 0, up.output
        assert alive_pids(_state_dir)
        assert (_state_dir / "twofiles-dev" / "local" / "sleeper").is_dir()
        down = runner.invoke(app, ["down", str(second), "--yes", "--force"])
        assert down.exit_code == 0, down.output
        assert "nothing left" in down.output
        assert alive_pids(_state_dir) == [], started_pids(_state_dir)
        assert not (_state_dir / "twofiles-dev" / "local").exists()
    finally:
        runner.invoke(app, ["down", str(first), "--yes", "--force"])
