"""The ``local`` target through the CLI: sandboxes with their own roscore, then nothing left behind."""

from __future__ import annotations

import socket
import subprocess
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.state import read_json
from tests.provision.conftest import make_workspace, ros_skip_reason

pytestmark = pytest.mark.ros

_REASON = ros_skip_reason()
if _REASON:
    pytest.skip(_REASON, allow_module_level=True)

MANIFEST = """name: demo
cloud: {provider: local}
nodes:
  - name: talker
    machine: t3.small
    launch: {package: fogtest, file: talker.launch, workspace: ws}
  - name: listener
    machine: t3.small
    launch: {package: fogtest, file: talker.launch, workspace: ws}
"""


def _processes_mentioning(text: str) -> list[str]:
    out = subprocess.run(["ps", "-eo", "pid,args"], capture_output=True, text=True).stdout
    return [line for line in out.splitlines() if text in line and "ps -eo" not in line]


def _listening(port: int) -> bool:
    with socket.socket() as sock:
        return sock.connect_ex(("127.0.0.1", port)) == 0


def test_local_sandboxes_run_provision_log_and_tear_down_cleanly(tmp_path: Path, _state_dir: Path) -> None:
    make_workspace(tmp_path / "ws")
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(MANIFEST)
    runner = CliRunner()
    first = runner.invoke(app, ["provision", str(manifest), "--health-timeout", "40"])
    assert first.exit_code == 0, first.output
    assert first.output.strip().endswith("2 of 2 host(s) changed")
    ports = read_json(_state_dir / "demo-dev" / "local" / "ports.json")
    assert len({p for host in ports.values() for p in host.values()}) == 4, "each sandbox has its own ports"
    assert all(_listening(host["master"]) for host in ports.values())

    again = runner.invoke(app, ["provision", str(manifest)])
    assert again.exit_code == 0, again.output
    assert again.output.strip().endswith("no changes")

    logs = runner.invoke(app, ["logs", "talker", str(manifest), "-n", "50"])
    assert logs.exit_code == 0 and "process[fog_talker-1]: started with pid" in logs.output
    shell = runner.invoke(app, ["ssh", "listener", str(manifest), "--print"])
    sandbox = _state_dir / "demo-dev" / "local" / "listener"
    assert shell.output.strip() == f"(cd {sandbox} && bash --rcfile {sandbox}/env/ros.sh -i)"

    down = runner.invoke(app, ["provision", str(manifest), "--teardown"])
    assert down.exit_code == 0, down.output
    assert _processes_mentioning(str(_state_dir)) == []
    assert not any(_listening(p) for host in ports.values() for p in host.values())
    assert sorted(p.name for p in (_state_dir / "demo-dev" / "local").iterdir()) == ["ports.json"]


def test_a_failing_host_exits_non_zero_with_its_line(tmp_path: Path, _state_dir: Path) -> None:
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text("name: boxed\ncloud: {provider: local}\nnodes:\n"
                        "  - {name: talker, machine: t3.small, command: ['/nonexistent/fogiac-test-node']}\n")
    try:
        result = CliRunner().invoke(app, ["provision", str(manifest)])
    finally:  # a failed host is left for teardown, as a failed up is left for down: take it down here
        down = CliRunner().invoke(app, ["provision", str(manifest), "--teardown"])
    assert down.exit_code == 0, down.output
    assert _processes_mentioning(str(_state_dir)) == []  # nothing of the failed host runs on (it had restarted)
    assert result.exit_code == 1
    assert "1 of 1 host(s) failed" in result.output
    # the node's program does not exist: the host's line names the node, what is wrong and the log's last line
    assert "error: talker: node-talker unhealthy: process not running; log: " in result.output
    assert "/nonexistent/fogiac-test-node: No such file or directory" in result.output
