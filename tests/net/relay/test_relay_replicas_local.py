"""Replicas end to end on ``local`` (issue 24): ``fogiac up`` of a node with ``replicas: 2`` runs it in two
sandboxes, each with its roscore and relay cloud end, and one replica group at the edge; a robot's requests
are all answered exactly once while one replica's cloud end is killed mid-run, and ``fogiac status`` shows
both replicas' figures. Real parts throughout: fogiac's CLI, the supervisor, roscores, rospy nodes."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.procs import free_port
from tests.net.relay.relay_support import Master, Procs, wait_for

pytestmark = pytest.mark.ros
NODES = Path(__file__).with_name("replica_nodes.py")


def test_up_with_two_replicas_answers_every_request_once_while_one_dies(
        ros_ready: None, tmp_path: Path, _state_dir: Path, procs: Procs) -> None:
    with _two_echo_replicas("echoes", "/echo", tmp_path, _state_dir) as (runner, manifest, sandboxes, replicas, edge):
        robot = procs.spawn([sys.executable, str(NODES), "robot", "/echo/request", "/echo/reply", "--count", "60",
                             "--rate", "10", "--wait", "3"], edge.env)
        wait_for(lambda: sum(line.startswith("{") for line in robot.lines) >= 20, 90, "a third of the replies")
        relay = sandboxes / "echo-r1" / "run" / "relay-cloud.child"
        with contextlib.suppress(ProcessLookupError):  # replica 1's cloud end dies; its supervisor restarts it
            os.kill(int(relay.read_text().split()[0]), signal.SIGKILL)
        wait_for(lambda: "done" in robot.lines, 120, "the robot's run")
        answered = [json.loads(line)["i"] for line in robot.lines if line.startswith("{")]
        assert sorted(answered) == list(range(60))  # every request answered, none twice
        wait_for(lambda: sum(r.get("won", 0) for r in replicas().values()) >= 60, 15, "the figures written")
        figures = replicas()
        assert set(figures) == {"echo-r1", "echo-r2"}
        assert all(r["group"] == "echo" and r["count"] == 2 for r in figures.values())
        assert sum(r["answers"] for r in figures.values()) > 60  # both answered: copies were dropped
        shown = runner.invoke(app, ["status", str(manifest), "--target", "local"], terminal_width=200)
        assert "replicas (first reply wins)" in shown.output and "echo-r1" in shown.output, shown.output


def test_up_with_two_replicas_and_one_stopped_node_the_other_wins(
        ros_ready: None, tmp_path: Path, _state_dir: Path, procs: Procs) -> None:
    """Two sandboxes; replica 1's node is stopped (SIGSTOP: a stalled host) for the robot's whole run: every
    request is answered once, all by replica 2, and status names replica 1 as not answering."""
    with _two_echo_replicas("stalls", "/stall", tmp_path, _state_dir) as (runner, manifest, sandboxes, replicas, edge):
        # both answer a first request before the stall (a node that never answered is not yet "silent")
        probe = procs.spawn([sys.executable, str(NODES), "robot", "/stall/request", "/stall/reply", "--count", "5",
                             "--rate", "5", "--wait", "2", "--base", "500"], edge.env)
        wait_for(lambda: "done" in probe.lines, 90, "the probe run")
        wait_for(lambda: all(r.get("answers", 0) >= 5 for r in replicas().values()), 15, "both replicas answering")
        before = {host: r["won"] for host, r in replicas().items()}
        node = int((sandboxes / "echo-r1" / "run" / "node-echo.child").read_text().split()[0])
        os.kill(node, signal.SIGSTOP)
        try:
            robot = procs.spawn([sys.executable, str(NODES), "robot", "/stall/request", "/stall/reply", "--count",
                                 "40", "--rate", "10", "--wait", "3"], edge.env)
            wait_for(lambda: "done" in robot.lines, 120, "the robot's run")
            answered = [json.loads(line)["i"] for line in robot.lines if line.startswith("{")]
            assert sorted(answered) == list(range(40))  # every request answered, none twice
            wait_for(lambda: replicas()["echo-r2"]["won"] - before["echo-r2"] >= 40, 15, "the figures written")
            figures = replicas()
            assert figures["echo-r1"]["won"] == before["echo-r1"]  # the stalled replica won nothing
            assert figures["echo-r1"]["health"] == "silent" and figures["echo-r2"]["health"] == "ok", figures
        finally:
            os.kill(node, signal.SIGCONT)


@contextlib.contextmanager
def _two_echo_replicas(stack: str, prefix: str, tmp_path: Path, state_dir: Path) -> Iterator[
        tuple[CliRunner, Path, Path, Callable[[], dict[str, dict]], Master]]:
    """``fogiac up`` of an echo node with ``replicas: 2`` on ``local`` (its topics PREFIX/request and PREFIX/reply),
    both replicas linked; yields the runner, the manifest, the sandboxes' folder, a reader of each replica's
    figures in ``fogiac status --json`` and the edge master; ``fogiac down`` on the way out, which must succeed."""
    edge_port = free_port()
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(f"""name: {stack}
cloud: {{provider: local}}
edge: {{ros_master: "http://127.0.0.1:{edge_port}"}}
nodes:
  - name: echo
    machine: t3.micro
    command: [{sys.executable}, {NODES}, echo, {prefix}/request, {prefix}/reply, --name, echo]
    replicas: 2
    topics: {{in: [{prefix}/request], out: [{prefix}/reply]}}
""")
    runner = CliRunner()
    try:
        up = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes", "--start-edge-master"])
        assert up.exit_code == 0, up.output

        def replicas() -> dict[str, dict]:
            status = runner.invoke(app, ["status", str(manifest), "--target", "local", "--json"])
            assert status.exit_code == 0, status.output
            return {link["host"]: link["replica"] for link in json.loads(status.output)["relays"]}

        wait_for(lambda: all(r.get("connected") for r in replicas().values()), 60, "both replicas linked")
        uri = f"http://127.0.0.1:{edge_port}/"
        edge = Master(uri, dict(os.environ, ROS_MASTER_URI=uri, ROS_HOSTNAME="127.0.0.1",
                                ROS_HOME=str(tmp_path / "ros"), ROS_LOG_DIR=str(tmp_path / "ros" / "log")))
        yield runner, manifest, state_dir / f"{stack}-dev" / "local", replicas, edge
    finally:
        down = runner.invoke(app, ["down", str(manifest), "--target", "local", "--yes"])
    assert down.exit_code == 0, down.output
