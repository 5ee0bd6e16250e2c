"""Issue 34, ROS 1 on ``local``: ``serve: per_robot`` runs one instance of a node per robot, in its namespace.

Three robots, each a real ROS master of its own (started by fogiac) with its own client process, and a SLAM-like
stand-in that keeps state: it counts the scans it has seen and answers each with its count and its namespace.
``up`` runs one instance per robot in the node's sandbox (``node-slam@arm1``..., each its own pid, its ROS name
``/arm1/slam``); each robot's scans reach its own instance only (every robot's counts run 1, 2, 3... though
all three send at once, and each answer names the robot's own namespace); the access file lists the node
under ``per_robot`` and adds none of its bare topics to any robot; arm1's certificate is refused arm2's
instance's output at the cloud end. ``status`` and ``logs`` name each instance (``slam@arm2``). A 4th robot
added starts its instance and edge end only (every other pid kept); dropped, only those stop. ``fogiac robot
revoke arm3`` still cuts arm3's link within 10 s, the others' kept, nothing restarted.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import socket
import subprocess
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.certs import edge_role
from fogiac.cli import app
from fogiac.net.relay import framing
from fogiac.net.relay.framing import Kind
from fogiac.net.relay.session import read_frame
from fogiac.net.relay.tls import client_context, relay_name
from fogiac.procs import free_port
from fogiac.provision import supervise
from fogiac.state import StackState, read_json
from tests.conftest import REPO
from tests.fleet.test_fleet_robot_revoke import _wait
from tests.fleet.test_fleet_up_local import _opened, _pids
from tests.plugins.install import installed
from tests.support.procs import alive, alive_pids, started_pids

pytestmark = [
    pytest.mark.ros,
    pytest.mark.skipif(shutil.which("roscore") is None, reason="needs Debian's ros-core (roscore)"),
]

NAME = "perrobot"
STACK = f"{NAME}-dev"

SLAM = textwrap.dedent("""\
    import rospy
    from std_msgs.msg import Header
    rospy.init_node("slam")
    print("slam up as", rospy.get_name(), flush=True)
    seen = []  # this instance's own state: the scans it has seen
    count = rospy.Publisher("/slam/count", Header, queue_size=100)
    def scan(m):
        seen.append(m.frame_id)
        count.publish(Header(stamp=m.stamp, frame_id=f"{rospy.get_namespace()}|{len(seen)}|{m.frame_id}"))
    rospy.Subscriber("/scan", Header, scan, queue_size=100)
    rospy.spin()
""")

# A robot's client on its own master: scans (its namespace's /scan) until its instance answers (the links are
# up), then SCANS numbered scans; prints every answer it heard as [namespace, count, scan].
CLIENT = textwrap.dedent("""\
    import json, sys, time
    import rospy
    from std_msgs.msg import Header
    robot, scans = sys.argv[1], int(sys.argv[2])
    rospy.init_node("client_" + robot, disable_signals=True)
    got = []
    rospy.Subscriber(f"/{robot}/slam/count", Header, lambda m: got.append(m.frame_id.split("|")), queue_size=1000)
    pub = rospy.Publisher(f"/{robot}/scan", Header, queue_size=1000)
    deadline, k = time.monotonic() + 150, 0
    while not got:
        if time.monotonic() > deadline:
            print(json.dumps({"error": "no answer to a ping"}))
            sys.exit(1)
        pub.publish(Header(frame_id=f"ping{k}"))
        k += 1
        time.sleep(0.5)
    time.sleep(3)  # every robot linked, every ping answered: all three send at once
    for i in range(scans):
        pub.publish(Header(frame_id=f"scan{i}"))
        time.sleep(0.1)
    deadline = time.monotonic() + 60
    while sum(g[2].startswith("scan") for g in got) < scans and time.monotonic() < deadline:
        time.sleep(0.2)
    time.sleep(2)  # late or stray answers show up too
    print(json.dumps(got))
""")
SCANS = {"arm1": 4, "arm2": 6, "arm3": 8, "arm4": 3}


def _manifest(path: Path, ports: dict[str, int], slam: Path) -> None:
    robots = "".join(f'  - {{name: {name}, ros_master: "http://127.0.0.1:{port}"}}\n' for name, port in ports.items())
    path.write_text(f"""name: {NAME}
cloud: {{provider: local}}
robots:
{robots}nodes:
  - name: slam
    machine: t3.micro
    command: [{sys.executable}, "{slam}"]
    topics: {{in: [/scan], out: [/slam/count]}}
    serve: per_robot
""")


def _clients(ports: dict[str, int], cwd: Path) -> dict[str, list[list[str]]]:
    """Every robot's client at once, each on its own master; robot -> the answers it heard."""
    running = {}
    for robot, port in ports.items():
        env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{port}", "ROS_HOSTNAME": "127.0.0.1",
               "PYTHONPATH": str(REPO)}
        running[robot] = subprocess.Popen([sys.executable, "-c", CLIENT, robot, str(SCANS[robot])], env=env, cwd=cwd,
                                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    reports = {}
    for robot, proc in running.items():
        out, err = proc.communicate(timeout=300)
        assert proc.returncode == 0, f"{robot}: {out[-2000:]} {err[-3000:]}"
        reports[robot] = json.loads(out.strip().splitlines()[-1])
    return reports


@contextlib.contextmanager
def _linked_as(certs: Path, robot: str, address: str) -> Iterator[socket.socket]:
    """A bare edge with ``robot``'s certificate: TLS and HELLO to the slam host's cloud end."""
    host, port = address.rsplit(":", 1)
    raw = socket.create_connection((host, int(port)), timeout=10)
    sock = client_context(certs, edge_role(STACK, robot)).wrap_socket(raw, server_hostname=relay_name(STACK, "slam"))
    try:
        sock.sendall(framing.encode(framing.json_frame(Kind.HELLO, {"role": "edge", "version": 1})))
        assert read_frame(sock).kind is Kind.HELLO
        yield sock
    finally:
        sock.close()


def _own_state_only(robot: str, answers: list[list[str]]) -> None:
    """Every answer from ``robot``'s own instance, whose count rose by one per scan of ``robot``'s alone."""
    assert {ns for ns, _, _ in answers} == {f"/{robot}/"}, (robot, answers)
    counts = [int(n) for _, n, _ in answers]
    assert counts == list(range(1, len(answers) + 1)), (robot, answers)  # no other robot's scan counted
    assert [s for _, _, s in answers if s.startswith("scan")] == [f"scan{i}" for i in range(SCANS[robot])], answers


def test_a_per_robot_node_runs_one_instance_per_robot_each_with_its_own_state(tmp_path: Path,
                                                                               _state_dir: Path) -> None:
    ports = {name: free_port() for name in ("arm1", "arm2", "arm3")}
    slam = tmp_path / "slam.py"
    slam.write_text(SLAM)
    manifest = tmp_path / "fogiac.yaml"
    _manifest(manifest, ports, slam)
    runner = CliRunner()
    stack = StackState(STACK)
    sandbox = _state_dir / STACK / "local" / "slam"
    try:
        up = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes", "--start-edge-master"])
        assert up.exit_code == 0, up.output
        # One supervised instance per robot, each its own process; no instance under the bare name.
        run = sandbox / "run"
        instances = {p.stem for p in run.glob("node-slam*.pid")}
        assert instances == {f"node-slam@{name}" for name in ports}, instances
        children = {name: (run / f"node-slam@{name}.child").read_text().split()[0] for name in ports}
        assert len(set(children.values())) == 3
        rules = json.loads((sandbox / "certs" / "fleet.json").read_text())
        assert rules["per_robot"] == [{"node": "slam", "in": ["/scan"], "out": ["/slam/count"]}]
        assert all(robot["topics"] == [] for robot in rules["robots"].values())  # no bare /scan for anyone
        assert "shared" not in rules  # a per-robot node's answers are its own robot's: nothing to route

        reports = _clients(ports, tmp_path)
        for robot, answers in reports.items():
            _own_state_only(robot, answers)
        status = runner.invoke(app, ["status", str(manifest), "--target", "local", "--json"])
        assert status.exit_code == 0 and all(f'"slam@{name}"' in status.output for name in ports), status.output
        logs = runner.invoke(app, ["logs", "slam@arm2", str(manifest)])
        assert logs.exit_code == 0 and "slam up as /arm2/slam" in logs.output, logs.output
        bare = runner.invoke(app, ["logs", "slam", str(manifest)])
        assert bare.exit_code == 1 and "node 'slam' runs one instance per robot: name one (slam@arm1, slam@arm2, " \
            "slam@arm3)" in bare.output, bare.output

        # A 4th robot: its instance and its edge end start; every other process keeps its pid.
        host_before, edge_before = _pids(sandbox), _pids(stack.edge)
        four = {**ports, "arm4": free_port()}
        _manifest(manifest, four, slam)
        again = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes", "--start-edge-master"])
        assert again.exit_code == 0, again.output
        host_now = _pids(sandbox)
        assert {k: v for k, v in host_now.items() if "arm4" not in k} == host_before
        assert {k for k in host_now if "arm4" in k} == {"run/node-slam@arm4.pid"}
        assert {name: (run / f"node-slam@{name}.child").read_text().split()[0] for name in ports} == children
        edge_now = _pids(stack.edge)
        assert {k: v for k, v in edge_now.items() if "arm4" not in k} == edge_before
        _own_state_only("arm4", _clients({"arm4": four["arm4"]}, tmp_path)["arm4"])

        # Dropped again: only its instance and its edge end stop.
        _manifest(manifest, ports, slam)
        dropped = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes"])
        assert dropped.exit_code == 0, dropped.output
        assert _pids(sandbox) == host_before and _pids(stack.edge) == edge_before

        # Revoked: arm3's link is cut within 10 s (its instance keeps running, unreachable); nothing restarts.
        def linked(robot: str) -> bool | None:
            return (read_json(stack.edge / f"relay-edge-slam@{robot}.stats.json") or {}).get("connected")

        with installed(tmp_path / "verb", "robotverb", {"fogiac.commands": {"robot": "fogiac.cli.robots"}}):
            revoked = runner.invoke(app, ["robot", "revoke", "arm3", str(manifest), "--target", "local"])
        assert revoked.exit_code == 0, revoked.output
        assert _wait("arm3's link cut", lambda: linked("arm3") is False, 10) < 10
        assert linked("arm1") and linked("arm2")
        assert _pids(sandbox) == host_before and _pids(stack.edge) == edge_before

        # At the cloud end, arm1's certificate is given its own instance's output and refused arm2's. arm1's own
        # edge end stops first, or it would take its session back (one session per identity).
        supervise.stop(stack.edge, "relay-edge-slam@arm1")
        (edge,) = [e for e in stack.get(StackState.EDGES) if e["name"] == "arm1"]
        with _linked_as(stack.certs, "arm1", edge["relays"]["slam"]) as sock:
            opened = _opened(sock, ("/arm2/slam/count", "/arm1/slam/count"), seconds=8)
        assert "/arm1/slam/count" in opened and "/arm2/slam/count" not in opened, opened
    finally:
        down = runner.invoke(app, ["down", str(manifest), "--target", "local", "--yes"])
    assert down.exit_code == 0, down.output
    assert alive_pids(_state_dir) == []
    assert [pid for pid in started_pids(_state_dir) if alive(pid)] == []
