"""A node that cannot run is never reported healthy (issue 35 item 6).

A program that exits at once is restarted by its supervisor forever: the health check passed on a
moment it happened to be running (``alive``), or once any node was registered with the host's master,
fogiac's own relay end included (``any``, the container runtime's check); ``status`` said ``running``
with restarts climbing, and a second ``up`` said "no changes". Health now means the service's own
process has stayed up (:data:`supervise.STAYED_UP_S`) and, for ``any``, a node other than fogiac's own is
registered; ``status`` says ``crash-looping`` with the program's last line; provisioning fails while a
node crash-loops, on a re-run too.
"""

from __future__ import annotations

import os
import shutil
import signal
import threading
import xmlrpc.client
import xmlrpc.server
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.provision import supervise
from tests.provision.test_supervise import _status, _sup, _wait, run_dir
from tests.support.nodes import script_node_manifest

__all__ = ["run_dir"]  # the supervisor tests' run folder fixture, found by pytest in this module's names
ROS = pytest.mark.skipif(shutil.which("roscore") is None, reason="needs Debian's ros-core (roscore)")


def test_a_program_that_exits_soon_after_starting_is_not_alive(run_dir: Path) -> None:
    """It runs half a second each time: the supervisor restarts it, and a check landing in that half
    second passed it."""
    _sup(run_dir, "start", "flaky", "--", "bash", "-c", "echo cannot open /dev/ttyUSB0; sleep 0.5; exit 1")
    ok, detail = supervise.health(run_dir, "flaky", check="alive", master="http://127.0.0.1:9", timeout=4)
    assert not ok, detail
    assert detail.startswith(("process not running; ", "pid ")) and detail.endswith("; log: cannot open /dev/ttyUSB0")
    assert _wait(lambda: _status(run_dir, "flaky").get("crash_looping") is True)
    assert _status(run_dir, "flaky")["last_line"] == "cannot open /dev/ttyUSB0"


def test_a_crash_loop_is_unhealthy_at_its_fourth_exit_not_at_the_timeout(run_dir: Path) -> None:
    """Health waited out its whole timeout (30 s by default) on a program that exits at once, for the verdict
    it could give after a few exits: it now answers while the supervisor waits to restart the program after
    its CRASH_LOOP_EXITS-th exit (an 8 s backoff), so no further restart has happened."""
    _sup(run_dir, "start", "broken", "--", "bash", "-c", "echo no such device; exit 1")
    ok, detail = supervise.health(run_dir, "broken", check="alive", master="http://127.0.0.1:9", timeout=60)
    assert not ok and detail == "process not running; log: no such device", detail
    assert _status(run_dir, "broken")["restarts"] == supervise.CRASH_LOOP_EXITS


def test_a_program_that_dies_a_few_times_then_stays_up_is_healthy(run_dir: Path, tmp_path: Path) -> None:
    """A node that exits while something it needs comes up (twice, here) is not a crash loop."""
    tries = tmp_path / "tries"
    _sup(run_dir, "start", "late", "--", "bash", "-c",
         f"echo x >>{tries}; [ $(wc -l <{tries}) -gt 2 ] || {{ echo master not up yet; exit 1; }}; exec sleep 300")
    ok, detail = supervise.health(run_dir, "late", check="alive", master="http://127.0.0.1:9", timeout=60)
    assert ok and detail.startswith("pid "), detail
    assert _status(run_dir, "late")["restarts"] == 2


def test_a_program_that_stays_up_is_healthy_and_not_crash_looping(run_dir: Path) -> None:
    _sup(run_dir, "start", "steady", "--", "sleep", "300")
    ok, detail = supervise.health(run_dir, "steady", check="alive", master="http://127.0.0.1:9", timeout=30)
    assert ok and detail.startswith("pid "), detail
    assert "crash_looping" not in _status(run_dir, "steady")


class _FakeNode:
    """A ROS 1 node's slave API answering getPid, registered on a real master under ``name``."""

    def __init__(self, master: str, name: str) -> None:
        self.server = xmlrpc.server.SimpleXMLRPCServer(("127.0.0.1", 0), logRequests=False, allow_none=True)
        self.server.register_function(lambda caller: [1, "", os.getpid()], "getPid")
        threading.Thread(target=self.server.serve_forever, daemon=True).start()
        uri = f"http://127.0.0.1:{self.server.server_address[1]}/"
        xmlrpc.client.ServerProxy(master).registerPublisher(name, "/chatter", "std_msgs/String", uri)

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()


@ROS
def test_fogiacs_own_relay_end_is_not_a_containers_node(run_dir: Path, tmp_path: Path) -> None:
    from tests.support.ros import roscore  # noqa: PLC0415

    with roscore(tmp_path) as env:
        master = env["ROS_MASTER_URI"]
        relay = _FakeNode(master, "/fogiac_relay_cloud")
        try:
            _sup(run_dir, "start", "node-det", "--", "sleep", "300")  # the engine's client, running on
            ok, detail = supervise.health(run_dir, "node-det", check="any", master=master, timeout=3)
            assert not ok and detail.startswith(f"no node but fogiac's own registered with {master}"), detail
            own = _FakeNode(master, "/detector")
            try:
                ok, detail = supervise.health(run_dir, "node-det", check="any", master=master, timeout=30)
                assert ok and detail == "registered /detector", detail
            finally:
                own.close()
        finally:
            relay.close()


CRASHER = """#!/bin/bash
# runs until a flag file exists, then (as a node whose config went bad) exits at once
if [ -e {flag} ]; then echo "fatal: config {flag} says no"; exit 2; fi
exec sleep 600
"""


@ROS
def test_provision_fails_while_a_node_crash_loops_and_status_says_so(tmp_path: Path, _state_dir: Path) -> None:
    flag = tmp_path / "broken"
    manifest = script_node_manifest(tmp_path, "loops", CRASHER.format(flag=flag))
    runner = CliRunner()
    try:
        first = runner.invoke(app, ["provision", str(manifest), "--health-timeout", "40"])
        assert first.exit_code == 0, first.output
        run_dir = _state_dir / "loops-dev" / "local" / "talker" / "run"
        flag.write_text("")
        os.kill(_status(run_dir, "node-talker")["child"], signal.SIGKILL)
        assert _wait(lambda: _status(run_dir, "node-talker").get("crash_looping") is True)
        again = runner.invoke(app, ["provision", str(manifest), "--health-timeout", "5"])
        assert again.exit_code == 1, again.output
        assert "no changes" not in again.output
        errors = [line for line in again.output.splitlines() if line.startswith("error: ")]
        assert len(errors) == 1 and errors[0].startswith("error: talker: node-talker unhealthy: "), again.output
        assert errors[0].endswith(f"log: fatal: config {flag} says no"), errors[0]
        status = runner.invoke(app, ["status", str(manifest)], env={"COLUMNS": "250"})
        assert status.exit_code == 0, status.output
        (row,) = [line for line in status.output.splitlines() if "talker" in line and "│" in line]
        assert "crash-looping" in row and "running" not in row, status.output
        assert f"talker: node talker is crash-looping; its last line: fatal: config {flag} says no" in \
            status.output.splitlines(), status.output
    finally:
        down = runner.invoke(app, ["provision", str(manifest), "--teardown"])
        assert down.exit_code == 0, down.output
