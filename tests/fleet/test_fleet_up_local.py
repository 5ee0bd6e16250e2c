"""Issue 34, ROS 1 on ``local``: ``fogiac up`` deploys a fleet, each robot its own edge end, certificate and access.

Three robots, each a real ROS master of its own (started by fogiac, as the other local tests do) with its own
client process, and a shared stand-in planner in one sandbox that answers every ``/plan/request`` on
``/plan/reply`` and also publishes ``/arm2/status``, a topic in robot arm2's namespace. What ``up`` must have
built: the sandbox's ``fleet.json`` beside its cloud end's certificates (each robot by its identity, the
planner's topics, no robot another's namespace, the planner's request/reply pair), one supervised edge end per
robot (``...@arm1``), every robot's request answered exactly once and to that robot only (equal stamps from
all three robots included), arm2's status heard by arm2 alone, and a certificate of arm1 refused arm2's topic at
the cloud end. Adding a 4th robot to the manifest and running ``up`` again starts only its edge end (the host's
processes and the other robots' edge ends keep their pids); dropping it stops only its edge end; ``down``
stops every one.
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
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.certs import edge_identity, edge_role
from fogiac.cli import app
from fogiac.net.relay import framing
from fogiac.net.relay.framing import Kind
from fogiac.net.relay.session import read_frame
from fogiac.net.relay.tls import client_context, relay_name
from fogiac.procs import free_port
from fogiac.provision import supervise
from fogiac.state import StackState
from tests.conftest import REPO
from tests.support.procs import alive, alive_pids, started_pids

pytestmark = [
    pytest.mark.ros,
    pytest.mark.skipif(shutil.which("roscore") is None, reason="needs Debian's ros-core (roscore)"),
]

NAME = "fleet"
STACK = f"{NAME}-dev"

PLANNER = textwrap.dedent("""\
    import rospy
    from std_msgs.msg import Header
    rospy.init_node("planner")
    reply = rospy.Publisher("/plan/reply", Header, queue_size=100)
    status = rospy.Publisher("/arm2/status", Header, queue_size=10)
    rospy.Subscriber("/plan/request", Header,
                     lambda m: reply.publish(Header(seq=m.seq, stamp=m.stamp, frame_id=m.frame_id)), queue_size=100)
    rate = rospy.Rate(5)
    while not rospy.is_shutdown():
        status.publish(Header(frame_id="arm2 status"))
        rate.sleep()
""")

# A robot's client: pings until its first answer comes back (the links are up), then sends REQUESTS numbered
# requests whose stamps every robot shares (equal stamps from different robots), and reports every reply it heard
# and how many of arm2's status messages reached it.
CLIENT = textwrap.dedent("""\
    import json, sys, time
    import rospy
    from std_msgs.msg import Header
    robot, count = sys.argv[1], int(sys.argv[2])
    rospy.init_node("client_" + robot, disable_signals=True)
    got, status = [], []
    rospy.Subscriber("/plan/reply", Header, lambda m: got.append(m.frame_id), queue_size=1000)
    rospy.Subscriber("/arm2/status", Header, lambda m: status.append(m.frame_id), queue_size=100)
    pub = rospy.Publisher("/plan/request", Header, queue_size=1000)
    deadline, k = time.monotonic() + 150, 0
    while not any(g.startswith(robot + ":ping") for g in got):
        if time.monotonic() > deadline:
            print(json.dumps({"error": "no answer to a ping", "got": got}))
            sys.exit(1)
        pub.publish(Header(stamp=rospy.Time(1000, k), frame_id=f"{robot}:ping:{k}"))
        k += 1
        time.sleep(0.5)
    time.sleep(2)  # every robot is linked before the numbered requests: all three run at once
    mine = [f"{robot}:{i}" for i in range(count)]
    for i, frame in enumerate(mine):
        pub.publish(Header(stamp=rospy.Time(2000, i), frame_id=frame))
        time.sleep(0.1)
    deadline = time.monotonic() + 60
    while not set(mine) <= set(got) and time.monotonic() < deadline:
        time.sleep(0.2)
    time.sleep(3)  # late or duplicate replies show up too
    print(json.dumps({"got": [g for g in got if ":ping:" not in g], "status": len(status)}))
""")
REQUESTS = 8


def _manifest(path: Path, ports: dict[str, int], planner: Path) -> None:
    robots = "".join(f'  - {{name: {name}, ros_master: "http://127.0.0.1:{port}"}}\n' for name, port in ports.items())
    path.write_text(f"""name: {NAME}
cloud: {{provider: local}}
robots:
{robots}nodes:
  - name: planner
    machine: t3.micro
    command: [{sys.executable}, "{planner}"]
    topics: {{in: [/plan/request], out: [/plan/reply, /arm2/status]}}
""")


def _clients(ports: dict[str, int], cwd: Path) -> dict[str, dict]:
    """Every robot's client at once, each on its own master; robot -> what it reported."""
    running = {}
    for robot, port in ports.items():
        env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{port}", "ROS_HOSTNAME": "127.0.0.1",
               "PYTHONPATH": str(REPO)}
        running[robot] = subprocess.Popen([sys.executable, "-c", CLIENT, robot, str(REQUESTS)], env=env, cwd=cwd,
                                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    reports = {}
    for robot, proc in running.items():
        out, err = proc.communicate(timeout=300)
        assert proc.returncode == 0, f"{robot}: {out[-2000:]} {err[-3000:]}"
        reports[robot] = json.loads(out.strip().splitlines()[-1])
    return reports


def _pids(folder: Path) -> dict[str, int]:
    """service -> its supervisor's pid, for every supervised process under ``folder``."""
    return {str(p.relative_to(folder)): int(p.read_text().split()[0]) for p in folder.rglob("*.pid")}


def _edge_ends(stack: StackState) -> set[str]:
    return {p.stem for p in stack.edge.glob("relay-edge-*.pid")}


@contextlib.contextmanager
def _linked_as(certs: Path, robot: str, address: str) -> Iterator[socket.socket]:
    """A bare edge with ``robot``'s certificate from the stack's folder: TLS and HELLO to the planner's cloud end."""
    host, port = address.rsplit(":", 1)
    raw = socket.create_connection((host, int(port)), timeout=10)
    sock = client_context(certs, edge_role(STACK, robot)).wrap_socket(raw, server_hostname=relay_name(STACK, "planner"))
    try:
        sock.sendall(framing.encode(framing.json_frame(Kind.HELLO, {"role": "edge", "version": 1})))
        assert read_frame(sock).kind is Kind.HELLO
        yield sock
    finally:
        sock.close()


def _opened(sock: socket.socket, topics: tuple[str, ...], *, seconds: float) -> set[str]:
    """SUBSCRIBE to ``topics``, then the topics the cloud end opened (started sending) within ``seconds``."""
    for n, topic in enumerate(topics):
        sock.sendall(framing.encode(framing.json_frame(Kind.SUBSCRIBE, {"topic": topic, "compression": "none"},
                                                       topic=n)))
    opened: set[str] = set()
    deadline = time.monotonic() + seconds
    sock.settimeout(1)
    while time.monotonic() < deadline:
        try:
            frame = read_frame(sock)
        except TimeoutError:
            continue
        except (OSError, framing.FrameError):
            break
        if frame.kind is Kind.OPEN:
            opened.add(str(framing.parse_json(frame).get("topic")))
    return opened


def _fleet(tmp_path: Path) -> tuple[dict[str, int], Path, Path]:
    """Three robots' master ports and, in ``tmp_path``, the fleet's manifest and its shared stand-in planner."""
    ports = {name: free_port() for name in ("arm1", "arm2", "arm3")}
    planner = tmp_path / "planner.py"
    planner.write_text(PLANNER)
    manifest = tmp_path / "fogiac.yaml"
    _manifest(manifest, ports, planner)
    return ports, manifest, planner


def test_up_deploys_a_fleet_each_robot_its_own_edge_end_and_access(tmp_path: Path, _state_dir: Path) -> None:
    ports, manifest, planner = _fleet(tmp_path)
    runner = CliRunner()
    stack = StackState(STACK)
    sandbox = _state_dir / STACK / "local" / "planner"
    try:
        up = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes", "--start-edge-master"])
        assert up.exit_code == 0, up.output
        assert "planner: relay 127.0.0.1:" in up.output and "<-> robots arm1, arm2, arm3" in up.output

        # The access file beside the cloud end's certificates: each robot by its certificate, the planner's
        # topics for all three, arm2's status for arm2 alone (its namespace), nobody revoked; never world-readable.
        access = sandbox / "certs" / "fleet.json"
        assert access.stat().st_mode & 0o077 == 0
        rules = json.loads(access.read_text())
        assert rules == {"revoked": [], "robots": {
            name: {"identity": edge_identity(STACK, name),
                   "topics": ["/arm2/status"] * (name == "arm2") + ["/plan/reply", "/plan/request"]}
            for name in ports}, "shared": [  # the planner's replies go to the robot that asked, by their stamp
            {"node": "planner", "requests": ["/plan/request"], "replies": ["/plan/reply"], "match": "header.stamp"}]}
        assert _edge_ends(stack) == {f"relay-edge-planner@{name}" for name in ports}

        reports = _clients(ports, tmp_path)
        for robot, report in reports.items():
            # Every request answered exactly once, to its own robot only, though all three robots stamp their
            # requests alike (equal stamps in flight at once) and all subscribe the one reply topic.
            assert sorted(report["got"]) == sorted(f"{robot}:{i}" for i in range(REQUESTS)), (robot, report)
        assert reports["arm2"]["status"] > 0  # arm2's own namespace reaches arm2 ...
        assert reports["arm1"]["status"] == 0 and reports["arm3"]["status"] == 0  # ... and no other robot
        status = runner.invoke(app, ["status", str(manifest), "--target", "local", "--json"])
        assert status.exit_code == 0, status.output  # a deployed fleet's status answers (its rows: fleetstatus)

        # A 4th robot: the manifest edited, up again. Its edge end starts; the sandbox's processes (master,
        # planner, cloud end) and the other robots' edge ends keep their pids; the access file lists it.
        host_before, edge_before = _pids(sandbox), _pids(stack.edge)
        planner_child = (sandbox / "run" / "node-planner.child").read_text().split()[0]
        four = {**ports, "arm4": free_port()}
        _manifest(manifest, four, planner)
        again = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes", "--start-edge-master"])
        assert again.exit_code == 0, again.output
        assert _pids(sandbox) == host_before
        assert (sandbox / "run" / "node-planner.child").read_text().split()[0] == planner_child
        edge_now = _pids(stack.edge)
        assert {k: v for k, v in edge_now.items() if "arm4" not in k} == edge_before
        assert {k for k in edge_now if "arm4" in k} == {"relay-edge-planner@arm4.pid", "edge-master@arm4.pid"}
        assert set(json.loads(access.read_text())["robots"]) == set(four)
        report = _clients({"arm4": four["arm4"]}, tmp_path)["arm4"]
        assert sorted(report["got"]) == sorted(f"arm4:{i}" for i in range(REQUESTS)) and report["status"] == 0, report

        # Dropped again: only its edge end (and the master fogiac ran for it) stop; nothing else moves.
        _manifest(manifest, ports, planner)
        dropped = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes"])
        assert dropped.exit_code == 0, dropped.output
        assert "robot arm4: its edge end stopped" in dropped.output
        assert _pids(sandbox) == host_before and _pids(stack.edge) == edge_before
        assert set(json.loads(access.read_text())["robots"]) == set(ports)

        # At the cloud end, arm1's certificate is refused arm2's topic (which the topic policy lets cross: arm2
        # hears it) and given the shared reply topic. arm1's own edge end stops first, or it would take its
        # session back (one session per identity).
        supervise.stop(stack.edge, "relay-edge-planner@arm1")
        (edge,) = [e for e in stack.get(StackState.EDGES) if e["name"] == "arm1"]
        with _linked_as(stack.certs, "arm1", edge["relays"]["planner"]) as sock:
            opened = _opened(sock, ("/arm2/status", "/plan/reply"), seconds=8)
        assert "/plan/reply" in opened and "/arm2/status" not in opened, opened
    finally:
        down = runner.invoke(app, ["down", str(manifest), "--target", "local", "--yes"])
    assert down.exit_code == 0, down.output
    assert alive_pids(_state_dir) == []
    assert [pid for pid in started_pids(_state_dir) if alive(pid)] == []
    assert not (_state_dir / STACK / "local").exists()
