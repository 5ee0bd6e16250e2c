"""Issue 34: ``fogiac robot revoke NAME`` cuts one robot of a deployed fleet off within 10 s with no manifest edit and
no process restarted; the record keeps it revoked across ``up``; ``fogiac robot restore NAME`` links it again.

The fleet of ``test_fleet_up_local`` on ``local``: three robots on real masters, a shared stand-in planner. The verb
is installed for the test the way a plug-in's is (``tests/plugins/install.py``) until fogiac is reinstalled with
its new entry point.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.state import StackState, read_json
from tests.fleet.test_fleet_up_local import REQUESTS, STACK, _clients, _fleet, _pids, pytestmark
from tests.plugins.install import installed
from tests.support.procs import alive_pids

__all__ = ["pytestmark"]


def _stats(stack: StackState, robot: str) -> dict[str, object]:
    return read_json(stack.edge / f"relay-edge-planner@{robot}.stats.json") or {}


def _connected(stack: StackState, robot: str) -> bool | None:
    connected = _stats(stack, robot).get("connected")
    return connected if isinstance(connected, bool) else None


def _wait(what: str, check: object, timeout: float) -> float:
    started = time.monotonic()
    while not check():  # type: ignore[operator]
        assert time.monotonic() - started < timeout, what
        time.sleep(0.2)
    return time.monotonic() - started


def test_revoke_cuts_a_robot_off_and_restore_lets_it_back(tmp_path: Path, _state_dir: Path) -> None:
    ports, manifest, _ = _fleet(tmp_path)
    runner = CliRunner()
    stack = StackState(STACK)
    sandbox = _state_dir / STACK / "local" / "planner"
    access = sandbox / "certs" / "fleet.json"
    local = ["--target", "local"]
    with installed(tmp_path / "verb", "robotverb", {"fogiac.commands": {"robot": "fogiac.cli.robots"}}):
        try:
            up = runner.invoke(app, ["up", str(manifest), *local, "--yes", "--start-edge-master"])
            assert up.exit_code == 0, up.output
            _wait("every robot linked", lambda: all(_connected(stack, r) for r in ports), 60)
            host_before, edge_before = _pids(sandbox), _pids(stack.edge)

            bad = runner.invoke(app, ["robot", "revoke", "arm9", str(manifest), *local])
            assert bad.exit_code == 1 and "no robot 'arm9' in robots: (arm1, arm2, arm3)" in bad.output, bad.output

            revoked = runner.invoke(app, ["robot", "revoke", "arm3", str(manifest), *local])
            assert revoked.exit_code == 0, revoked.output
            took = _wait("arm3's link cut", lambda: _connected(stack, "arm3") is False, 10)
            assert took < 10
            _wait("arm3's edge told why", lambda: _stats(stack, "arm3").get("link_refused") == "revoked", 10)
            assert json.loads(access.read_text())["revoked"] == ["arm3"] and stack.get(StackState.REVOKED) == ["arm3"]
            assert _connected(stack, "arm1") and _connected(stack, "arm2")  # the others carry on ...
            reports = _clients({"arm1": ports["arm1"]}, tmp_path)
            assert sorted(reports["arm1"]["got"]) == sorted(f"arm1:{i}" for i in range(REQUESTS))  # ... answered
            assert _pids(sandbox) == host_before and _pids(stack.edge) == edge_before  # nothing restarted

            again = runner.invoke(app, ["up", str(manifest), *local, "--yes"])  # the record keeps it revoked
            assert again.exit_code == 0, again.output
            assert json.loads(access.read_text())["revoked"] == ["arm3"]
            time.sleep(3)
            assert _connected(stack, "arm3") is False

            restored = runner.invoke(app, ["robot", "restore", "arm3", str(manifest), *local])
            assert restored.exit_code == 0, restored.output
            assert "its edge end links again now" in restored.output  # woken: it does not wait out its backoff
            assert json.loads(access.read_text())["revoked"] == [] and stack.get(StackState.REVOKED) is None
            _wait("arm3 linked again", lambda: _connected(stack, "arm3") is True, 30)
            report = _clients({"arm3": ports["arm3"]}, tmp_path)["arm3"]
            assert sorted(report["got"]) == sorted(f"arm3:{i}" for i in range(REQUESTS)), report
            assert _pids(sandbox) == host_before
        finally:
            down = runner.invoke(app, ["down", str(manifest), *local, "--yes"])
    assert down.exit_code == 0, down.output
    assert alive_pids(_state_dir) == []
