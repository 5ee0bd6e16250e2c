"""Issue 17's defects, each as the user's session on the local target: commands in order, the
lines a user reads, the exit codes. Real roscore, relay and planner; nothing is left running."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.procs import free_port
from tests.conftest import EXAMPLES, REPO
from tests.support.procs import alive_pids

needs_ros = pytest.mark.skipif(shutil.which("roscore") is None, reason="needs Debian's ros-core (roscore)")
pytestmark = [pytest.mark.ros, needs_ros]


@dataclass
class Session:
    """One user's shell: a manifest file, a state directory, and fogiac commands run in order."""

    manifest: Path
    state: Path
    edge_port: int

    def __call__(self, *args: str) -> tuple[int, list[str]]:
        result = CliRunner().invoke(app, [*args], env={"FOGIAC_STATE_DIR": str(self.state), "COLUMNS": "200"})
        return result.exit_code, [line.rstrip() for line in result.output.splitlines()]

    def fogiac(self, *args: str, **kw: object) -> subprocess.Popen[str]:
        env = {**os.environ, "FOGIAC_STATE_DIR": str(self.state), "COLUMNS": "200"}
        return subprocess.Popen([sys.executable, "-m", "fogiac", *args], cwd=self.manifest.parent, env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)  # type: ignore[call-overload]


def motion_planning(folder: Path, state: Path) -> Session:
    """examples/motion-planning.yaml with its edge master on a free port (fogiac starts it)."""
    folder.mkdir(parents=True, exist_ok=True)
    port = free_port()
    manifest = folder / "fogiac.yaml"
    manifest.write_text((EXAMPLES / "motion-planning.yaml").read_text().replace(
        "ros_master: http://localhost:11311", f"ros_master: http://127.0.0.1:{port}"))
    return Session(manifest=manifest, state=state, edge_port=port)


def request_a_path(session: Session, *extra: str) -> subprocess.CompletedProcess[str]:
    """The robot's side: the motion-planning client against the edge master, through the relay."""
    env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{session.edge_port}", "ROS_HOSTNAME": "127.0.0.1",
           "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, "-m", "workloads.motion_planning", "client", "easy", *extra],
                          env=env, capture_output=True, text=True, timeout=240, cwd=REPO)


@pytest.fixture(scope="module")
def deployed(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Session, list[str]]]:
    """One `fogiac up --target local` for the read-only sessions below; down (and proof) at the end."""
    root = tmp_path_factory.mktemp("deployed")
    session = motion_planning(root / "checkout", root / "state")
    code, up = session("up", str(session.manifest), "--target", "local", "--yes", "--start-edge-master")
    try:
        assert code == 0, "\n".join(up)
        yield session, up
    finally:
        code, down = session("down", str(session.manifest), "--yes")
        assert code == 0, "\n".join(down)
        assert alive_pids(session.state) == []


def test_1_status_down_logs_ssh_follow_the_target_up_recorded(deployed: tuple[Session, list[str]]) -> None:
    session, _ = deployed
    m = str(session.manifest)
    code, out = session("status", m)  # the manifest says aws; the deployment is local
    assert code == 0 and any("motion-planning-dev (local)" in line for line in out), out
    assert any(re.search(r"planner .* running", line) for line in out), out
    code, out = session("logs", "planner", m)
    assert code == 0 and out and not out[0].startswith("error"), out
    ready = _wait_for_log(session, "planner", "motion_planning: ready")  # the node's own line, once it has loaded
    assert ready, out
    code, out = session("logs", "plannr", m)
    assert (code, out) == (1, [f"error: {m} has no node 'plannr'; its nodes: planner"])
    code, out = session("ssh", "planner", m, "--print")
    assert code == 0 and "bash --rcfile" in out[-1], out
    code, out = session("status", m, "--target", "aws")
    assert (code, out) == (1, ["error: stack 'motion-planning-dev' is deployed to target local, not aws; "
                               "drop --target, or `fogiac down` it first"])
    code, out = session("down", m, "--target", "aws", "--yes")
    assert code == 1 and len(out) == 1 and "deployed to target local, not aws" in out[0], out


def _wait_for_log(session: Session, node: str, text: str, *, attempts: int = 120) -> list[str]:
    """`fogiac logs NODE` until a line holds TEXT (the planner loads its problems before it says ready)."""
    for _ in range(attempts):
        code, out = session("logs", node, str(session.manifest))
        assert code == 0, out
        if any(text in line for line in out):
            return out
        time.sleep(0.5)
    return []


def test_3_another_manifest_with_the_same_stack_name_is_refused(deployed: tuple[Session, list[str]],
                                                                tmp_path: Path) -> None:
    session, _ = deployed
    other = tmp_path / "other-checkout" / "fogiac.yaml"
    other.parent.mkdir()
    other.write_text(session.manifest.read_text().replace(str(session.edge_port), str(free_port())))
    mine, theirs = session.manifest.resolve(), other.resolve()
    for verb in (["up", "--yes"], ["down", "--yes"]):
        code, out = session(verb[0], str(other), *verb[1:])
        assert (code, out) == (1, [f"error: stack 'motion-planning-dev' was made by {mine}, not {theirs}; use "
                                   "that file, or give this one another name: or --env (or pass --force to take "
                                   "it over)"]), out
    code, out = session("status", str(other))
    assert code == 1 and out[0].startswith(f"error: stack 'motion-planning-dev' was made by {mine}"), out
    code, out = session("status", str(session.manifest))  # still there, untouched
    assert code == 0 and any("running" in line for line in out), out


def test_4_plan_detailed_exitcode_is_0_right_after_up(deployed: tuple[Session, list[str]]) -> None:
    session, _ = deployed
    for _ in range(2):
        code, out = session("plan", str(session.manifest), "--detailed-exitcode")
        assert code == 0, out
        assert out[0] == "fogiac plan motion-planning-dev (--env dev): target local"
    changed = session.manifest.read_text()
    session.manifest.write_text(changed.replace("disk_gb: 30", "disk_gb: 40"))
    try:
        code, _ = session("plan", str(session.manifest), "--detailed-exitcode")
        assert code == 2
    finally:
        session.manifest.write_text(changed)


def test_7_status_shows_directions_latency_address_uptime_and_cost(deployed: tuple[Session, list[str]]) -> None:
    session, up = deployed
    answer = request_a_path(session)
    assert answer.returncode == 0, answer.stderr[-2000:]
    # 10: one readable line per problem on a terminal's worth of output, JSON only when asked for
    assert re.fullmatch(r"easy: solved, \d+ poses; \d+\.\d{3} s round trip, \d+\.\d{3} s planning",
                        answer.stdout.strip()), answer.stdout
    deadline = time.monotonic() + 15  # the relay writes its figures once a second
    while True:
        code, out = session("status", str(session.manifest), "--json")
        doc = json.loads("\n".join(out))
        topics = {t["topic"]: t for t in doc["relays"][0].get("topics", [])}
        path = topics.get("/motion_planning/path", {})
        if path.get("msgs") and path.get("latency_ms") is not None or time.monotonic() > deadline:
            break
        time.sleep(0.5)
    assert topics["/motion_planning/request"]["direction"] == "in"  # as the manifest says
    assert topics["/motion_planning/path"]["direction"] == "out"
    assert path["latency_ms"] is not None and path["latency_ms"] >= 0, topics
    (host,) = doc["hosts"]
    assert re.fullmatch(r"127\.0\.0\.1:\d+", host["address"]) and host["uptime_s"] >= 0 and host["cost_usd"] == 0
    code, out = session("status", str(session.manifest))
    assert code == 0
    cells = [[c.strip() for c in line.split("│")[1:-1]] for line in out if "/motion_planning/" in line]
    rows = {row[2]: row for row in cells}
    assert rows["/motion_planning/request"][3:5] == ["in", "1"], cells  # dir, msgs
    assert rows["/motion_planning/path"][3:5] == ["out", "1"], cells
    assert re.fullmatch(r"\d+\.\d\d", rows["/motion_planning/path"][7]), cells  # latency ms, after the request
    # 9: the provisioning table's address is what the edge dials, not a folder
    assert any(re.search(r"│ planner │ 127\.0\.0\.1:\d+ ", line) for line in up), up


def test_9_up_on_local_shows_the_plan_before_it_deploys(deployed: tuple[Session, list[str]]) -> None:
    _, up = deployed
    plan_at = up.index("fogiac plan motion-planning-dev (--env dev): target local")
    provisioned_at = next(i for i, line in enumerate(up) if line.startswith("provisioning:"))
    assert plan_at < provisioned_at
    assert "cost: $0.0000 per hour (about $0.00 per month (730 h) if left running)" in up


def test_9_down_counts_what_it_removed_and_knows_when_nothing_was_there(tmp_path: Path) -> None:
    session = motion_planning(tmp_path / "checkout", tmp_path / "state")
    m = str(session.manifest)
    code, out = session("down", m, "--target", "local", "--yes")
    assert (code, out) == (0, ["motion-planning-dev: not deployed; nothing to remove"])
    assert not (session.state / "motion-planning-dev").exists()  # down of nothing creates nothing
    code, out = session("up", m, "--target", "local", "--yes", "--start-edge-master")
    assert code == 0, out
    code, out = session("down", m, "--yes")
    assert code == 0 and out[-1].startswith("motion-planning-dev: removed 5 (edge process edge-master, "), out
    assert out[-1].endswith("planner process ros-master); nothing left"), out
    code, out = session("down", m, "--yes")  # again: the record says where it was, and that it is gone
    assert (code, out) == (0, ["motion-planning-dev: not deployed; nothing to remove"])
    assert alive_pids(session.state) == []


def _wait_for(condition: object, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not condition():  # type: ignore[operator]
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.05)


def test_2_ctrl_c_during_up_says_what_is_left_and_down_removes_it(tmp_path: Path) -> None:
    session = motion_planning(tmp_path / "checkout", tmp_path / "state")
    m = str(session.manifest)
    up = session.fogiac("up", m, "--target", "local", "--yes", "--start-edge-master")
    try:
        stack = session.state / "motion-planning-dev"
        # the moment the issue saw: processes have started, up is not finished
        _wait_for(lambda: (stack / "edge" / "edge-master.pid").exists() or up.poll() is not None, 60)
        up.send_signal(signal.SIGINT)
        stdout, stderr = up.communicate(timeout=120)
    finally:
        if up.poll() is None:
            up.kill()
    assert up.returncode == 130, stdout + stderr
    # up's step lines (issue 35 item 17) come first, the last saying where the Ctrl-C fell; then what was left
    first = stderr.splitlines().index("interrupted: up of motion-planning-dev stopped part-way; this is what it left:")
    steps, lines = stderr.splitlines()[:first], stderr.splitlines()[first:]
    assert steps and all(re.fullmatch(r"[\w-]+: [\w' -]+( \S+)? (…|\S+ \(\d+\.\ds\))", line) for line in steps), stderr
    assert steps[-1].endswith("…") or " interrupted (" in steps[-1], stderr
    assert any("edge-master (pid" in line for line in lines), stderr
    assert lines[-1] == f"`fogiac down {m}` removes it; `fogiac up {m}` completes it", stderr
    assert "Traceback" not in stderr
    code, out = session("status", m)
    assert code == 0 and out[0].startswith("motion-planning-dev: partial: the last up did not finish"), out
    code, out = session("down", m, "--yes")
    assert code == 0 and out[-1].startswith("motion-planning-dev: removed ") and "nothing left" in out[-1], out
    assert alive_pids(session.state) == []
    code, out = session("status", m, "--target", "local")
    assert out == ["motion-planning-dev: not deployed"]
