"""Issue 34, ROS 1 on ``local``: ``fogiac up`` deploys a fleet, each robot its own edge end, certificate and access.

Three robots, each a real ROS master of its own (started by fogiac, as the other local tests do) with its own
client processes, and two nodes, each in its own sandbox (host): a shared stand-in planner that answers every
``/plan/request`` on ``/plan/reply`` and also publishes ``/arm2/status``, a topic in robot arm2's namespace; and a
SLAM-like stand-in served ``per_robot`` that keeps state (it counts the scans it has seen and answers each with
its count and its namespace). The three walks below share one deployment of that fleet (the module's ``fleet``),
and the rounds of clients and the 4th robot's visit that two of them look at are made once (``first_round``,
``fourth``), because deploying the same fleet once per walk spent most of each walk's minute on ``up`` and
``down``.

The shared planner (``test_up_deploys_...``): the sandbox's ``fleet.json`` beside its cloud end's certificates
(each robot by its identity, the planner's topics, no robot another's namespace, the planner's request/reply
pair), one supervised edge end per robot and host (``...@arm1``), every robot's request answered exactly once
and to that robot only (equal stamps from all three robots included), arm2's status heard by arm2 alone, and a
certificate of arm1 refused arm2's topic at the cloud end. Adding a 4th robot to the manifest and running ``up``
again starts only its edge ends (the hosts' processes and the other robots' edge ends keep their pids); dropping
it stops only those; ``down`` stops every one.

``serve: per_robot`` (``test_a_per_robot_node_...``): ``up`` runs one instance per robot in the node's sandbox
(``node-slam@arm1``..., each its own pid, its ROS name ``/arm1/slam``); each robot's scans reach its own instance
only (every robot's counts run 1, 2, 3... though all three send at once, and each answer names the robot's own
namespace); the access file lists the node under ``per_robot`` and adds none of its bare topics to any robot;
arm1's certificate is refused arm2's instance's output at the cloud end. ``status`` and ``logs`` name each
instance (``slam@arm2``). A 4th robot added starts its instance and edge ends only (every other pid kept);
dropped, only those stop.

``fogiac robot revoke NAME`` (``test_revoke_...``) cuts one robot off within 10 s at both hosts with no manifest
edit and no process restarted; the record keeps it revoked across ``up``; ``fogiac robot restore NAME`` links it
again. The verb is installed for the test the way a plug-in's is (``tests/plugins/install.py``) until fogiac is
reinstalled with its new entry point.

Each walk leaves the fleet as it found it (three robots, none revoked, every edge end linked), so they pass alone
and in any order.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import textwrap
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from fogiac.certs import edge_identity, edge_role
from fogiac.cli import app
from fogiac.net.relay import framing
from fogiac.net.relay.deploy import wake_robot
from fogiac.net.relay.framing import Kind
from fogiac.net.relay.session import read_frame
from fogiac.net.relay.tls import client_context, relay_name
from fogiac.procs import free_port
from fogiac.provision import supervise
from fogiac.state import StackState, read_json
from tests.conftest import REPO
from tests.fleet.fleet_support import pids as _pids
from tests.fleet.fleet_support import wait
from tests.plugins.install import installed
from tests.support.procs import alive, alive_pids, started_pids

__all__ = ["PLANNER", "REQUESTS", "_clients", "_pids"]  # the hosts and Zenoh fleet tests use them

pytestmark = [
    pytest.mark.ros,
    pytest.mark.skipif(shutil.which("roscore") is None, reason="needs Debian's ros-core (roscore)"),
]

NAME = "fleet"
STACK = f"{NAME}-dev"
HOSTS = ("planner", "slam")  # on local each node is its own sandbox (host)

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

# Every client of a round waits at this barrier, once it has heard its first answer (its links are up), before
# it sends its numbered messages: then all robots' clients send at once. BARRIER (a folder) and TOTAL (the
# round's clients) come after the client's own arguments.
_BARRIER = """\
    def all_linked(robot, kind, barrier, total, deadline):
        open(os.path.join(barrier, kind + "-" + robot), "w").close()
        while len(os.listdir(barrier)) < total:
            if time.monotonic() > deadline:
                print(json.dumps({"error": "not every client of the round heard an answer"}))
                sys.exit(1)
            time.sleep(0.05)
"""

# A robot's planner client: pings until its first answer comes back (the links are up), then sends REQUESTS
# numbered requests whose stamps every robot shares (equal stamps from different robots), and reports every reply
# it heard and how many of arm2's status messages reached it.
CLIENT = textwrap.dedent("""\
    import json, os, sys, time
    import rospy
    from std_msgs.msg import Header
""") + textwrap.dedent(_BARRIER) + textwrap.dedent("""\
    robot, count, barrier, total = sys.argv[1], int(sys.argv[2]), sys.argv[3], int(sys.argv[4])
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
        time.sleep(0.25)
    all_linked(robot, "plan", barrier, total, deadline)  # every robot linked: all of them run at once
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

# A robot's SLAM client on its own master: scans (its namespace's /scan) until its instance answers (the links are
# up), then SCANS numbered scans; prints every answer it heard as [namespace, count, scan].
SLAM_CLIENT = textwrap.dedent("""\
    import json, os, sys, time
    import rospy
    from std_msgs.msg import Header
""") + textwrap.dedent(_BARRIER) + textwrap.dedent("""\
    robot, scans, barrier, total = sys.argv[1], int(sys.argv[2]), sys.argv[3], int(sys.argv[4])
    rospy.init_node("slam_client_" + robot, disable_signals=True)
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
        time.sleep(0.25)
    all_linked(robot, "slam", barrier, total, deadline)  # every robot linked, every ping answered: all send at once
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
SCRIPTS = {"plan": CLIENT, "slam": SLAM_CLIENT}


def _manifest(path: Path, ports: Mapping[str, int], planner: Path, slam: Path) -> None:
    robots = "".join(f'  - {{name: {name}, ros_master: "http://127.0.0.1:{port}"}}\n' for name, port in ports.items())
    path.write_text(f"""name: {NAME}
cloud: {{provider: local}}
robots:
{robots}nodes:
  - name: planner
    machine: t3.micro
    command: [{sys.executable}, "{planner}"]
    topics: {{in: [/plan/request], out: [/plan/reply, /arm2/status]}}
  - name: slam
    machine: t3.micro
    command: [{sys.executable}, "{slam}"]
    topics: {{in: [/scan], out: [/slam/count]}}
    serve: per_robot
""")


def _round(ports: Mapping[str, int], cwd: Path, kinds: tuple[str, ...]) -> dict[str, dict[str, Any]]:
    """Every robot's clients of ``kinds`` (``plan``: the shared planner's, ``slam``: its per-robot instance's) at
    once, each on its robot's master, all sending their numbered messages together; kind -> robot -> its report."""
    barrier = tempfile.mkdtemp(dir=cwd, prefix="round-")
    running = {}
    for kind in kinds:
        for robot, port in ports.items():
            env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{port}", "ROS_HOSTNAME": "127.0.0.1",
                   "PYTHONPATH": str(REPO)}
            count = REQUESTS if kind == "plan" else SCANS[robot]
            argv = [sys.executable, "-c", SCRIPTS[kind], robot, str(count), barrier, str(len(ports) * len(kinds))]
            running[kind, robot] = subprocess.Popen(argv, env=env, cwd=cwd, stdout=subprocess.PIPE,
                                                    stderr=subprocess.PIPE, text=True)
    reports: dict[str, dict[str, Any]] = {kind: {} for kind in kinds}
    for (kind, robot), proc in running.items():
        out, err = proc.communicate(timeout=300)
        assert proc.returncode == 0, f"{kind} client of {robot}: {out[-2000:]} {err[-3000:]}"
        reports[kind][robot] = json.loads(out.strip().splitlines()[-1])
    return reports


def _clients(ports: Mapping[str, int], cwd: Path) -> dict[str, dict]:
    """Every robot's planner client at once, each on its own master; robot -> what it reported."""
    return _round(ports, cwd, ("plan",))["plan"]


def _edge_ends(stack: StackState) -> set[str]:
    return {p.stem for p in stack.edge.glob("relay-edge-*.pid")}


def _stats(stack: StackState, host: str, robot: str) -> dict[str, Any]:
    return read_json(stack.edge / f"relay-edge-{host}@{robot}.stats.json") or {}


def _connected(stack: StackState, robot: str, host: str = "planner") -> bool | None:
    connected = _stats(stack, host, robot).get("connected")
    return connected if isinstance(connected, bool) else None


@dataclass(frozen=True)
class Fleet:
    """The module's deployed fleet: three robots, the shared planner and the per-robot slam."""

    state: Path
    folder: Path  # the manifest, the nodes' programs, the clients' working folder
    manifest: Path
    planner: Path
    slam: Path
    ports: dict[str, int]
    up_output: str

    @property
    def stack(self) -> StackState:
        return StackState(STACK)

    def sandbox(self, host: str) -> Path:
        return self.state / STACK / "local" / host

    def access(self, host: str) -> Path:
        return self.sandbox(host) / "certs" / "fleet.json"

    def hosts_pids(self) -> dict[str, dict[str, int]]:
        return {host: _pids(self.sandbox(host)) for host in HOSTS}

    def up(self, *extra: str) -> Any:
        return CliRunner().invoke(app, ["up", str(self.manifest), "--target", "local", "--yes", *extra])

    def all_linked(self) -> bool:
        return all(_connected(self.stack, robot, host) for robot in self.ports for host in HOSTS)


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    """The fleet, up (``up --start-edge-master``) for the module's tests and down after the last; ``down`` stops
    every process it started and leaves no sandbox."""
    folder = tmp_path_factory.mktemp("fleet")
    state = tmp_path_factory.mktemp("fogiac-state")
    ports = {name: free_port() for name in ("arm1", "arm2", "arm3")}
    planner, slam, manifest = folder / "planner.py", folder / "slam.py", folder / "fogiac.yaml"
    planner.write_text(PLANNER)
    slam.write_text(SLAM)
    _manifest(manifest, ports, planner, slam)
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("FOGIAC_STATE_DIR", str(state))
        runner = CliRunner()
        try:
            up = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes", "--start-edge-master"])
            assert up.exit_code == 0, up.output
            yield Fleet(state, folder, manifest, planner, slam, ports, up.output)
        finally:
            down = runner.invoke(app, ["down", str(manifest), "--target", "local", "--yes"])
        assert down.exit_code == 0, down.output
        assert alive_pids(state) == []
        assert [pid for pid in started_pids(state) if alive(pid)] == []
        assert not (state / STACK / "local").exists()


@pytest.fixture(autouse=True)
def _state_dir(fleet: Fleet, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Every test of the module works on the fleet's state (tests/conftest.py gives each test a fresh one)."""
    monkeypatch.setenv("FOGIAC_STATE_DIR", str(fleet.state))
    return fleet.state


@pytest.fixture(scope="module")
def first_round(fleet: Fleet) -> dict[str, dict[str, Any]]:
    """The three robots' planner and slam clients, all at once: kind -> robot -> its report."""
    return _round(fleet.ports, fleet.folder, ("plan", "slam"))


@dataclass(frozen=True)
class Fourth:
    """What a 4th robot's visit showed: its ``up``, its clients, the drop, and every pid before and after."""

    hosts_before: dict[str, dict[str, int]]
    edge_before: dict[str, int]
    planner_child: tuple[str, str]  # the planner's child before and after the 4th robot joined
    slam_children: tuple[dict[str, str], dict[str, str]]  # robot -> its instance's child, before and after
    grown_output: str
    hosts_grown: dict[str, dict[str, int]]
    edge_grown: dict[str, int]
    access_grown: dict[str, set[str]]  # host -> the robots its access file lists
    reports: dict[str, dict[str, Any]]  # kind -> {"arm4": its report}
    dropped_output: str
    hosts_dropped: dict[str, dict[str, int]]
    edge_dropped: dict[str, int]
    access_dropped: dict[str, set[str]]


@pytest.fixture(scope="module")
def fourth(fleet: Fleet) -> Fourth:
    """A 4th robot: the manifest edited, ``up`` again, its clients; then dropped again, ``up`` once more."""
    stack, run = fleet.stack, fleet.sandbox("slam") / "run"

    def children() -> tuple[str, dict[str, str]]:
        planner = (fleet.sandbox("planner") / "run" / "node-planner.child").read_text().split()[0]
        return planner, {name: (run / f"node-slam@{name}.child").read_text().split()[0] for name in fleet.ports}

    def robots() -> dict[str, set[str]]:
        return {host: set(json.loads(fleet.access(host).read_text())["robots"]) for host in HOSTS}

    hosts_before, edge_before = fleet.hosts_pids(), _pids(stack.edge)
    planner_before, slam_before = children()
    four = {**fleet.ports, "arm4": free_port()}
    _manifest(fleet.manifest, four, fleet.planner, fleet.slam)
    try:
        grown = fleet.up("--start-edge-master")
        assert grown.exit_code == 0, grown.output
        hosts_grown, edge_grown, access_grown = fleet.hosts_pids(), _pids(stack.edge), robots()
        planner_after, slam_after = children()
        reports = _round({"arm4": four["arm4"]}, fleet.folder, ("plan", "slam"))
    finally:
        _manifest(fleet.manifest, fleet.ports, fleet.planner, fleet.slam)  # dropped again
        dropped = fleet.up()
    assert dropped.exit_code == 0, dropped.output
    return Fourth(hosts_before, edge_before, (planner_before, planner_after), (slam_before, slam_after),
                  grown.output, hosts_grown, edge_grown, access_grown, reports, dropped.output, fleet.hosts_pids(),
                  _pids(stack.edge), robots())


@contextlib.contextmanager
def _linked_as(certs: Path, robot: str, host: str, address: str) -> Iterator[socket.socket]:
    """A bare edge with ``robot``'s certificate from the stack's folder: TLS and HELLO to ``host``'s cloud end."""
    name, port = address.rsplit(":", 1)
    raw = socket.create_connection((name, int(port)), timeout=10)
    sock = client_context(certs, edge_role(STACK, robot)).wrap_socket(raw, server_hostname=relay_name(STACK, host))
    try:
        sock.sendall(framing.encode(framing.json_frame(Kind.HELLO, {"role": "edge", "version": 1})))
        assert read_frame(sock).kind is Kind.HELLO
        yield sock
    finally:
        sock.close()


def _opened(sock: socket.socket, topics: tuple[str, ...], *, answered: Callable[[set[str]], bool],
            seconds: float) -> set[str]:
    """SUBSCRIBE to ``topics``, then the topics the cloud end opened (started sending) by the time ``answered``
    holds of them (each request answered: opened, or refused as the cloud end's stats count), or ``seconds``."""
    for n, topic in enumerate(topics):
        sock.sendall(framing.encode(framing.json_frame(Kind.SUBSCRIBE, {"topic": topic, "compression": "none"},
                                                       topic=n)))
    opened: set[str] = set()
    deadline = time.monotonic() + seconds
    sock.settimeout(0.2)
    while time.monotonic() < deadline and not answered(opened):
        try:
            frame = read_frame(sock)
        except TimeoutError:
            continue
        except (OSError, framing.FrameError):
            break
        if frame.kind is Kind.OPEN:
            opened.add(str(framing.parse_json(frame).get("topic")))
    return opened


def _cloud_refused(fleet: Fleet, host: str) -> int:
    """The requests ``host``'s cloud end has refused on its live links (its stats file, written every second)."""
    return int((read_json(fleet.sandbox(host) / "run" / "relay-cloud.stats.json") or {}).get("refused", 0))


@pytest.fixture(scope="module")
def probes(fleet: Fleet) -> dict[str, set[str]]:
    """At each cloud end, what arm1's certificate is given of its own topics and of arm2's: host -> the topics
    opened (``planner``: arm2's status and the shared reply; ``slam``: arm2's instance's output and arm1's). arm1's
    own edge ends stop first, or they would take their session back (one session per identity); ``up`` starts
    them again after."""
    stack = fleet.stack
    asked = {"planner": (("/arm2/status", "/plan/reply"), "/plan/reply"),
             "slam": (("/arm2/slam/count", "/arm1/slam/count"), "/arm1/slam/count")}
    (edge,) = [e for e in stack.get(StackState.EDGES) if e["name"] == "arm1"]
    found = {}
    for host, (topics, allowed) in asked.items():
        supervise.stop(stack.edge, f"relay-edge-{host}@arm1")
        before = _cloud_refused(fleet, host)
        with _linked_as(stack.certs, "arm1", host, edge["relays"][host]) as sock:
            found[host] = _opened(sock, topics, seconds=8,
                                  answered=lambda opened, h=host, a=allowed, b=before: (
                                      a in opened and _cloud_refused(fleet, h) > b))
    again = fleet.up("--start-edge-master")
    assert again.exit_code == 0, again.output
    wait("arm1 linked again", fleet.all_linked, 60)
    return found


def test_up_deploys_a_fleet_each_robot_its_own_edge_end_and_access(fleet: Fleet, first_round: dict[str, Any],
                                                                   fourth: Fourth,
                                                                   probes: dict[str, set[str]]) -> None:
    ports, stack, runner = fleet.ports, fleet.stack, CliRunner()
    assert "planner: relay 127.0.0.1:" in fleet.up_output and "<-> robots arm1, arm2, arm3" in fleet.up_output

    # The access file beside the cloud end's certificates: each robot by its certificate, the planner's
    # topics for all three, arm2's status for arm2 alone (its namespace), nobody revoked; never world-readable.
    access = fleet.access("planner")
    assert access.stat().st_mode & 0o077 == 0
    rules = json.loads(access.read_text())
    assert rules == {"revoked": [], "robots": {
        name: {"identity": edge_identity(STACK, name),
               "topics": ["/arm2/status"] * (name == "arm2") + ["/plan/reply", "/plan/request"]}
        for name in ports}, "shared": [  # the planner's replies go to the robot that asked, by their stamp
        {"node": "planner", "requests": ["/plan/request"], "replies": ["/plan/reply"], "match": "header.stamp"}]}
    assert _edge_ends(stack) == {f"relay-edge-{host}@{name}" for host in HOSTS for name in ports}

    reports = first_round["plan"]
    for robot, report in reports.items():
        # Every request answered exactly once, to its own robot only, though all three robots stamp their
        # requests alike (equal stamps in flight at once) and all subscribe the one reply topic.
        assert sorted(report["got"]) == sorted(f"{robot}:{i}" for i in range(REQUESTS)), (robot, report)
    assert reports["arm2"]["status"] > 0  # arm2's own namespace reaches arm2 ...
    assert reports["arm1"]["status"] == 0 and reports["arm3"]["status"] == 0  # ... and no other robot
    status = runner.invoke(app, ["status", str(fleet.manifest), "--target", "local", "--json"])
    assert status.exit_code == 0, status.output  # a deployed fleet's status answers (its rows: fleetstatus)

    # A 4th robot: the manifest edited, up again. Its edge ends start; the sandboxes' processes (masters,
    # planner, cloud ends) and the other robots' edge ends keep their pids; the access file lists it.
    assert fourth.hosts_grown["planner"] == fourth.hosts_before["planner"]
    assert fourth.planner_child[1] == fourth.planner_child[0]
    assert {k: v for k, v in fourth.edge_grown.items() if "arm4" not in k} == fourth.edge_before
    assert {k for k in fourth.edge_grown if "arm4" in k} == {
        "relay-edge-planner@arm4.pid", "relay-edge-slam@arm4.pid", "edge-master@arm4.pid"}
    assert fourth.access_grown["planner"] == {*ports, "arm4"}
    report = fourth.reports["plan"]["arm4"]
    assert sorted(report["got"]) == sorted(f"arm4:{i}" for i in range(REQUESTS)) and report["status"] == 0, report

    # Dropped again: only its edge ends (and the master fogiac ran for it) stop; nothing else moves.
    assert "robot arm4: its edge end stopped" in fourth.dropped_output
    assert fourth.hosts_dropped == fourth.hosts_before and fourth.edge_dropped == fourth.edge_before
    assert fourth.access_dropped["planner"] == set(ports)

    # At the cloud end, arm1's certificate is refused arm2's topic (which the topic policy lets cross: arm2
    # hears it) and given the shared reply topic.
    assert "/plan/reply" in probes["planner"] and "/arm2/status" not in probes["planner"], probes


def test_a_per_robot_node_runs_one_instance_per_robot_each_with_its_own_state(fleet: Fleet,
                                                                               first_round: dict[str, Any],
                                                                               fourth: Fourth,
                                                                               probes: dict[str, set[str]]) -> None:
    ports, manifest, runner = fleet.ports, fleet.manifest, CliRunner()
    sandbox = fleet.sandbox("slam")
    # One supervised instance per robot, each its own process; no instance under the bare name.
    run = sandbox / "run"
    instances = {p.stem for p in run.glob("node-slam*.pid")}
    assert instances == {f"node-slam@{name}" for name in ports}, instances
    children = {name: (run / f"node-slam@{name}.child").read_text().split()[0] for name in ports}
    assert len(set(children.values())) == 3
    rules = json.loads(fleet.access("slam").read_text())
    assert rules["per_robot"] == [{"node": "slam", "in": ["/scan"], "out": ["/slam/count"]}]
    assert all(robot["topics"] == [] for robot in rules["robots"].values())  # no bare /scan for anyone
    assert "shared" not in rules  # a per-robot node's answers are its own robot's: nothing to route

    for robot, answers in first_round["slam"].items():
        _own_state_only(robot, answers)
    status = runner.invoke(app, ["status", str(manifest), "--target", "local", "--json"])
    assert status.exit_code == 0 and all(f'"slam@{name}"' in status.output for name in ports), status.output
    logs = runner.invoke(app, ["logs", "slam@arm2", str(manifest)])
    assert logs.exit_code == 0 and "slam up as /arm2/slam" in logs.output, logs.output
    bare = runner.invoke(app, ["logs", "slam", str(manifest)])
    assert bare.exit_code == 1 and "node 'slam' runs one instance per robot: name one (slam@arm1, slam@arm2, " \
        "slam@arm3)" in bare.output, bare.output

    # A 4th robot: its instance and its edge ends start; every other process keeps its pid.
    before, grown = fourth.hosts_before["slam"], fourth.hosts_grown["slam"]
    assert {k: v for k, v in grown.items() if "arm4" not in k} == before
    assert {k for k in grown if "arm4" in k} == {"run/node-slam@arm4.pid"}
    assert fourth.slam_children[1] == fourth.slam_children[0]
    assert {k: v for k, v in fourth.edge_grown.items() if "arm4" not in k} == fourth.edge_before
    assert fourth.access_grown["slam"] == {*ports, "arm4"}
    _own_state_only("arm4", fourth.reports["slam"]["arm4"])

    # Dropped again: only its instance and its edge ends stop.
    assert fourth.hosts_dropped == fourth.hosts_before and fourth.edge_dropped == fourth.edge_before

    # At the cloud end, arm1's certificate is given its own instance's output and refused arm2's.
    assert "/arm1/slam/count" in probes["slam"] and "/arm2/slam/count" not in probes["slam"], probes


def _own_state_only(robot: str, answers: list[list[str]]) -> None:
    """Every answer from ``robot``'s own instance, whose count rose by one per scan of ``robot``'s alone."""
    assert {ns for ns, _, _ in answers} == {f"/{robot}/"}, (robot, answers)
    counts = [int(n) for _, n, _ in answers]
    assert counts == list(range(1, len(answers) + 1)), (robot, answers)  # no other robot's scan counted
    assert [s for _, _, s in answers if s.startswith("scan")] == [f"scan{i}" for i in range(SCANS[robot])], answers


def test_revoke_cuts_a_robot_off_and_restore_lets_it_back(fleet: Fleet, tmp_path: Path) -> None:
    ports, manifest, stack, runner = fleet.ports, str(fleet.manifest), fleet.stack, CliRunner()
    local = ["--target", "local"]
    with installed(tmp_path / "verb", "robotverb", {"fogiac.commands": {"robot": "fogiac.cli.robots"}}):
        wait("every robot linked", fleet.all_linked, 60)
        hosts_before, edge_before = fleet.hosts_pids(), _pids(stack.edge)

        bad = runner.invoke(app, ["robot", "revoke", "arm9", manifest, *local])
        assert bad.exit_code == 1 and "no robot 'arm9' in robots: (arm1, arm2, arm3)" in bad.output, bad.output

        revoked = runner.invoke(app, ["robot", "revoke", "arm3", manifest, *local])
        assert revoked.exit_code == 0, revoked.output
        for host in HOSTS:  # cut at each host's cloud end, the shared planner's and the per-robot slam's
            took = wait(f"arm3's link to {host} cut", lambda h=host: _connected(stack, "arm3", h) is False, 10)
            assert took < 10
            wait(f"arm3's edge told why by {host}", lambda h=host: _stats(stack, h, "arm3").get(
                "link_refused") == "revoked", 10)
            assert json.loads(fleet.access(host).read_text())["revoked"] == ["arm3"]
            assert _connected(stack, "arm1", host) and _connected(stack, "arm2", host)  # the others carry on ...
        assert stack.get(StackState.REVOKED) == ["arm3"]
        reports = _clients({"arm1": ports["arm1"]}, fleet.folder)
        assert sorted(reports["arm1"]["got"]) == sorted(f"arm1:{i}" for i in range(REQUESTS))  # ... answered
        assert fleet.hosts_pids() == hosts_before and _pids(stack.edge) == edge_before  # nothing restarted

        again = runner.invoke(app, ["up", manifest, *local, "--yes"])  # the record keeps it revoked
        assert again.exit_code == 0, again.output
        assert json.loads(fleet.access("planner").read_text())["revoked"] == ["arm3"]
        # arm3's edge end, woken to dial at once instead of at the end of its backoff, is refused again.
        log = stack.edge / "relay-edge-planner@arm3.log"
        refusals = log.read_text().count("refused this edge: revoked")
        wake_robot("arm3", folder=stack.edge)
        wait("arm3 refused again after up", lambda: log.read_text().count("refused this edge: revoked") > refusals, 20)
        assert _connected(stack, "arm3") is False

        restored = runner.invoke(app, ["robot", "restore", "arm3", manifest, *local])
        assert restored.exit_code == 0, restored.output
        assert "its edge end links again now" in restored.output  # woken: it does not wait out its backoff
        assert json.loads(fleet.access("planner").read_text())["revoked"] == [] and stack.get(
            StackState.REVOKED) is None
        wait("arm3 linked again", lambda: _connected(stack, "arm3") is True, 30)
        report = _clients({"arm3": ports["arm3"]}, fleet.folder)["arm3"]
        assert sorted(report["got"]) == sorted(f"arm3:{i}" for i in range(REQUESTS)), report
        assert fleet.hosts_pids() == hosts_before
        wait("arm3 linked again to every host", fleet.all_linked, 30)  # the fleet as the other tests find it
