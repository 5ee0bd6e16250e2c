"""Issue 26 item 28 with real parts: a local ``up`` whose node reads a named secret. The node gets the
value; the host's copy is a 0600 file; the recorded state, the plan and up's output never hold it."""

from __future__ import annotations

import os
import shutil
import stat
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.procs import free_port

pytestmark = [
    pytest.mark.ros,
    pytest.mark.skipif(shutil.which("roscore") is None, reason="needs Debian's ros-core (roscore)"),
]

SECRET = "s3cr3t-from-the-operator's-env"
FILED = "filed-pa55word"


def test_a_named_secret_reaches_the_node_and_nothing_else(tmp_path: Path, _state_dir: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("LOCAL_TOKEN", SECRET)
    (tmp_path / "db.pass").write_text(FILED + "\n")
    out = tmp_path / "seen"
    edge_port = free_port()
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(f"""\
name: secrets
cloud: {{provider: local, runtime: native}}
edge: {{ros_master: "http://127.0.0.1:{edge_port}"}}
nodes:
  - name: reader
    machine: t3.small
    command: [sh, -c, 'printf "%s|%s" "$API_TOKEN" "$DB_PASSWORD" > {out}.tmp && mv {out}.tmp {out} && exec sleep 600']
    env: {{API_TOKEN: {{secret: "env:LOCAL_TOKEN"}}, DB_PASSWORD: {{secret: "file:db.pass"}}, LOG_LEVEL: info}}
""")
    runner = CliRunner()
    try:
        up = runner.invoke(app, ["up", str(manifest), "--yes", "--start-edge-master"])
        assert up.exit_code == 0, up.output
        assert SECRET not in up.output and FILED not in up.output
        deadline = time.monotonic() + 60
        while not out.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert out.read_text() == f"{SECRET}|{FILED}"
        holders = [p for p in _state_dir.rglob("*") if p.is_file() and not p.is_symlink()
                   and (SECRET.encode() in p.read_bytes() or FILED.encode() in p.read_bytes())]
        assert holders and all(p.name == "node-reader.secret.sh" for p in holders), holders
        assert all(stat.S_IMODE(p.stat().st_mode) == 0o600 for p in holders)
        plan = runner.invoke(app, ["plan", str(manifest), "--json"])
        assert SECRET not in plan.output and "[secret env:LOCAL_TOKEN]" in plan.output
    finally:
        down = runner.invoke(app, ["down", str(manifest), "--yes"])
        assert down.exit_code == 0, down.output
    assert not any(SECRET.encode() in p.read_bytes() for p in _state_dir.rglob("*") if p.is_file())
    assert os.environ["LOCAL_TOKEN"] == SECRET
