"""A replicated node through the relay: real roscores (the robot's, and one per replica), cloud ends as
``fogiac relay cloud`` processes, rospy nodes asking and answering, the replica group in-process.

Asserts on counts and on which replica won, never on wall-clock thresholds."""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import signal
import sys
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pytest

from fogiac.certs import issue, new_bundle, save_bundle, save_pair
from fogiac.lifecycle.report import replicas_lines
from fogiac.manifest.schema import load_manifest
from fogiac.net.relay import EdgeConfig, TopicPolicy
from fogiac.net.relay.deploy import edge_links, edge_up
from fogiac.net.relay.replicas import GroupConfig, ReplicaGroup, ReplicaTarget
from fogiac.net.relay.tls import relay_name
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Replica, Route
from fogiac.provision import supervise
from tests.net.relay.relay_support import Master, Proc, Procs, free_port, wait_for
from tests.support.delayproxy import DelayProxy

pytestmark = pytest.mark.ros
NODES = Path(__file__).with_name("replica_nodes.py")
EXAMPLES = Path(__file__).parents[3] / "examples"


@pytest.fixture(scope="module")
def three_masters(ros_ready: None, tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Master, Master, Master]]:
    """The robot's master and one per replica (each replica on a host of its own)."""
    procs = Procs(tmp_path_factory.mktemp("roshome"))
    try:
        yield procs.roscore(), procs.roscore(), procs.roscore()
    finally:
        procs.close()


def cloud_end(procs: Procs, master: Master, certs: Path, req: str, rep: str) -> tuple[Proc, tuple[str, int]]:
    port = free_port()
    proc = procs.spawn([sys.executable, "-m", "fogiac", "relay", "cloud", "--listen", f"127.0.0.1:{port}",
                        "--master", master.uri, "--certs", str(certs), "--ros-host", "127.0.0.1",
                        "--out", req, "--in", rep, "--topics", ""],
                       dict(master.env, PYTHONPATH=os.getcwd()))
    return proc, ("127.0.0.1", port)


def two_replicas(procs: Procs, m0: Master, m1: Master, certs: Path, req: str, rep: str, *,
                 r0_args: tuple[str, ...] = ()) -> tuple[tuple[Proc, Proc], tuple[tuple[str, int], tuple[str, int]]]:
    """Each replica's host (masters ``m0``, ``m1``): its cloud end and its echo node, named r0 and r1.
    Returns the two cloud ends and the addresses the edge dials."""
    c0, a0 = cloud_end(procs, m0, certs, req, rep)
    c1, a1 = cloud_end(procs, m1, certs, req, rep)
    node(procs, m0, "echo", req, rep, "--name", "r0", *r0_args)
    node(procs, m1, "echo", req, rep, "--name", "r1")
    return (c0, c1), (a0, a1)


def node(procs: Procs, master: Master, *args: str) -> Proc:
    proc = procs.spawn([sys.executable, str(NODES), *args], master.env)
    wait_for(lambda: "ready" in proc.lines or proc.popen.poll() is not None, 30, f"replica node {args}")
    assert proc.popen.poll() is None, f"replica node {args} exited"
    return proc


@contextlib.contextmanager
def group(edge: Master, certs: Path, addresses: list[tuple[str, int]], req: str, rep: str, tmp_path: Path,
          **kw: object) -> Iterator[ReplicaGroup]:
    config = EdgeConfig(master_uri=edge.uri, certs=certs, ros_host="127.0.0.1", connect=("", 0), poll_interval=0.1,
                        backoff_max=0.5, dead_after=3.0, queue_depth=100,
                        policy=TopicPolicy(out_topics=(req,), in_topics=(rep,)),
                        caller_id="/fogiac_relay_replicas_test")
    targets = tuple(ReplicaTarget(i, f"r{i}", a, stats_file=tmp_path / f"relay-edge-r{i}.stats.json")
                    for i, a in enumerate(addresses))
    with ReplicaGroup(GroupConfig(edge=config, group="echo", replicas=targets,
                                  stats_file=tmp_path / "replicas.json", **kw)) as g:  # type: ignore[arg-type]
        wait_for(lambda: all(link.linked for link in g.links), 20, "every replica linked")
        yield g


def replies(robot: Proc) -> list[dict]:
    return [json.loads(line) for line in robot.lines if line.startswith("{")]


def run_robot(procs: Procs, edge: Master, req: str, rep: str, count: int, *, rate: float = 20.0, base: int = 1000,
              during: object = None) -> list[dict]:
    robot = node(procs, edge, "robot", req, rep, "--count", str(count), "--rate", str(rate), "--wait", "3",
                 "--base", str(base))
    if during is not None:
        wait_for(lambda: len(replies(robot)) >= count // 3, 60, "a third of the replies")
        during()  # type: ignore[operator]
    wait_for(lambda: "done" in robot.lines, 120, "the robot's run")
    return replies(robot)


def test_every_request_answered_once_while_a_replica_is_killed(three_masters: tuple[Master, Master, Master],
                                                               certs: Path, procs: Procs, tmp_path: Path) -> None:
    edge, m0, m1 = three_masters
    req, rep = "/kill/request", "/kill/reply"
    (c0, c1), (a0, a1) = two_replicas(procs, m0, m1, certs, req, rep)
    with group(edge, certs, [a0, a1], req, rep, tmp_path) as g:
        got = run_robot(procs, edge, req, rep, 90, during=lambda: procs.kill(c0, signal.SIGKILL))
        stats = g.stats()
    assert sorted(r["i"] for r in got) == list(range(90))  # every request answered, exactly once
    winners = Counter(r["from"] for r in got)
    assert winners["r1"] >= 60  # after the kill only r1 answers
    r0, r1 = stats["replicas"]
    assert r0["health"] == "down" and r1["health"] == "ok"
    assert r0["won"] + r1["won"] == stats["delivered"] == 90
    assert stats["duplicates_dropped"] == r0["late"] + r1["late"] > 0  # both answered before the kill
    written = json.loads((tmp_path / "replicas.json").read_text())
    assert written["group"] == "echo" and [r["host"] for r in written["replicas"]] == ["r0", "r1"]


def test_a_stopped_replica_leaves_the_healthy_one_winning(three_masters: tuple[Master, Master, Master],
                                                          certs: Path, procs: Procs, tmp_path: Path) -> None:
    edge, m0, m1 = three_masters
    req, rep = "/stall/request", "/stall/reply"
    (c0, c1), (a0, a1) = two_replicas(procs, m0, m1, certs, req, rep)
    with group(edge, certs, [a0, a1], req, rep, tmp_path, silent_after=1.0) as g:
        os.killpg(c0.popen.pid, signal.SIGSTOP)  # replica 0's link stalls: bytes go in, nothing comes out
        try:
            got = run_robot(procs, edge, req, rep, 60)
            stats = g.stats()
        finally:
            os.killpg(c0.popen.pid, signal.SIGCONT)
    assert sorted(r["i"] for r in got) == list(range(60))
    assert Counter(r["from"] for r in got) == {"r1": 60}  # the stalled replica never wins
    r0, r1 = stats["replicas"]
    assert r0["won"] == 0 and r0["health"] in ("silent", "down") and r1["won"] == 60 and r1["health"] == "ok"


def test_a_replica_behind_a_slow_link_leaves_the_healthy_one_winning(three_masters: tuple[Master, Master, Master],
                                                                     certs: Path, procs: Procs, tmp_path: Path) -> None:
    """Replica 0 answers every request, but through a user-space proxy that holds each chunk 400 ms each way
    (a slow link): the robot gets each reply once, from replica 1, and replica 0's copies are dropped as late."""
    edge, m0, m1 = three_masters
    req, rep = "/slow/request", "/slow/reply"
    _, (a0, a1) = two_replicas(procs, m0, m1, certs, req, rep)
    proxy = DelayProxy(a0, 0.4)
    try:
        with group(edge, certs, [("127.0.0.1", proxy.port), a1], req, rep, tmp_path) as g:
            got = run_robot(procs, edge, req, rep, 60, rate=10.0)
            wait_for(lambda: g.stats()["replicas"][0]["late"] >= 50, 20, "the slow replica's copies")
            stats = g.stats()
    finally:
        proxy.close()
    assert sorted(r["i"] for r in got) == list(range(60))  # every request answered, none twice
    winners = Counter(r["from"] for r in got)
    assert winners["r1"] >= 57, winners  # nearly all: the healthy replica's reply comes first
    r0, r1 = stats["replicas"]
    assert r0["won"] + r1["won"] == stats["delivered"] == 60
    assert r0["late"] >= 50 and r0["health"] == "ok"  # replica 0 answered too, only late; it is linked and alive


def test_delayed_hedge_asks_the_second_replica_only_when_the_first_is_late(
        three_masters: tuple[Master, Master, Master], certs: Path, procs: Procs, tmp_path: Path) -> None:
    edge, m0, m1 = three_masters
    req, rep = "/hedge/request", "/hedge/reply"
    (c0, c1), (a0, a1) = two_replicas(procs, m0, m1, certs, req, rep)
    with group(edge, certs, [a0, a1], req, rep, tmp_path, hedge="delayed", hedge_delay_s=2.0) as g:
        healthy = run_robot(procs, edge, req, rep, 20)
        before = g.stats()
        os.killpg(c0.popen.pid, signal.SIGSTOP)  # the first replica stops answering
        try:
            stalled = run_robot(procs, edge, req, rep, 10, rate=5.0, base=2000)
            after = g.stats()
        finally:
            os.killpg(c0.popen.pid, signal.SIGCONT)
    # While both answer within the delay, the second replica is never asked: half the traffic.
    assert sorted(r["i"] for r in healthy) == list(range(20))
    assert before["replicas"][1]["sent"] == 0 and before["duplicates_dropped"] == 0
    # Once the first is silent, every request still gets exactly one answer, from the second.
    assert sorted(r["i"] for r in stalled) == list(range(10))
    assert Counter(r["from"] for r in stalled) == {"r1": 10}
    assert after["replicas"][1]["won"] == 10


def test_a_field_other_than_the_stamp_matches_replies(three_masters: tuple[Master, Master, Master],
                                                      certs: Path, procs: Procs, tmp_path: Path) -> None:
    """``match: seq`` (std_msgs/Header's first field) keys replies by the field's raw bytes, found
    with the message definition the publisher sends; a field the replies do not copy from their request
    (``frame_id``: each replica writes its own name there) matches no request, and nothing passes."""
    edge, m0, m1 = three_masters
    req, rep = "/seq/request", "/seq/reply"
    _, (a0, a1) = two_replicas(procs, m0, m1, certs, req, rep)
    with group(edge, certs, [a0, a1], req, rep, tmp_path, match="seq") as g:
        got = run_robot(procs, edge, req, rep, 10)
        stats = g.stats()
    assert sorted(r["i"] for r in got) == list(range(10))
    assert stats["delivered"] == 10 and stats["duplicates_dropped"] == 10 and stats["unmatched"] == 0
    with group(edge, certs, [a0, a1], req, rep, tmp_path, match="frame_id") as g:
        got = run_robot(procs, edge, req, rep, 5, base=2000)
        stats = g.stats()
    # Issue 35 (2): a reply whose key names no request was delivered (here: each replica's first one).
    assert got == [] and stats["delivered"] == 0 and stats["unsolicited"] == 10


def test_requests_with_a_zero_stamp_are_each_answered_once(three_masters: tuple[Master, Master, Master],
                                                           certs: Path, procs: Procs, tmp_path: Path) -> None:
    """Issue 35 (8): five requests stamped 0 got one answer on ROS 1 (the others' replies were taken for
    copies of the first): each is answered once, never merged, whichever replica is first."""
    edge, m0, m1 = three_masters
    req, rep = "/zero/request", "/zero/reply"
    _, (a0, a1) = two_replicas(procs, m0, m1, certs, req, rep)
    with group(edge, certs, [a0, a1], req, rep, tmp_path) as g:
        robot = node(procs, edge, "robot", req, rep, "--count", "5", "--wait", "3", "--zero-stamp")
        wait_for(lambda: "done" in robot.lines, 120, "the robot's run")
        stats = g.stats()
    assert sorted(r["i"] for r in replies(robot)) == list(range(5))
    assert stats["delivered"] == 5 and stats["duplicates_dropped"] == 5


# A Header whose definition puts a self-referential type, then an array of a bad size, before seq.
HOSTILE = {"cycle": "Loop x\\nuint32 seq\\ntime stamp\\nstring frame_id\\n=====\\nMSG: std_msgs/Loop\\nLoop y\\n",
           "size": "float64[x] junk\\nuint32 seq\\ntime stamp\\nstring frame_id\\n"}


@pytest.mark.parametrize("hostile", sorted(HOSTILE))
def test_a_hostile_definition_refuses_only_that_replica(three_masters: tuple[Master, Master, Master],
                                                        certs: Path, procs: Procs, tmp_path: Path, hostile: str,
                                                        caplog: pytest.LogCaptureFixture) -> None:
    """Issue 35 (3): the first link's definition keyed every replica's replies, and a hostile one raised
    RecursionError or ValueError in the link that opened it. Each link now has its own reader: the hostile
    replica's replies are refused with a logged line, the healthy one answers every request."""
    edge, m0, m1 = three_masters
    req, rep = f"/hostile_{hostile}/request", f"/hostile_{hostile}/reply"
    _, (a0, a1) = two_replicas(procs, m0, m1, certs, req, rep, r0_args=("--definition", HOSTILE[hostile]))
    with group(edge, certs, [a0, a1], req, rep, tmp_path, match="seq") as g:
        got = run_robot(procs, edge, req, rep, 10)
        stats = g.stats()
        assert all(link.linked for link in g.links) and g.links[0].reconnects == 0  # the link itself stays
    assert sorted(r["i"] for r in got) == list(range(10)) and {r["from"] for r in got} == {"r1"}
    assert stats["replicas"][0]["won"] == 0 and stats["replicas"][1]["won"] == 10
    refused = [r.getMessage() for r in caplog.records if "its replies there are refused" in r.getMessage()]
    assert refused and all(m.startswith(f"replica 1 of echo: {rep}: its message definition") for m in refused)


def test_replies_of_another_type_than_the_stated_one_are_refused(three_masters: tuple[Master, Master, Master],
                                                                 certs: Path, procs: Procs, tmp_path: Path) -> None:
    """The manifest's message_types is what a reply's type is checked against (a replica's word is not)."""
    edge, m0, m1 = three_masters
    req, rep = "/stated/request", "/stated/reply"
    _, (a0, a1) = two_replicas(procs, m0, m1, certs, req, rep)
    with group(edge, certs, [a0, a1], req, rep, tmp_path, types=((rep, "std_msgs/msg/Header"),)) as g:
        assert len(run_robot(procs, edge, req, rep, 3)) == 3  # the stated type, in ROS 2 spelling
    with group(edge, certs, [a0, a1], req, rep, tmp_path, types=((rep, "geometry_msgs/PoseStamped"),)) as g:
        wait_for(lambda: g.merge(rep).refused == {0, 1}, 20, "both replicas' replies refused")
        assert g.merge(rep).pub is None and "/fogiac_relay_replicas_test" not in edge.publishers(rep)


def replica_route(host: str, index: int, req: str, rep: str) -> Route:
    return Route(host=host, connect_via="loopback", port=0, auto=False, to_cloud=(req,), to_edge=(rep,), listed=(),
                 compression=(), queue_size=100, replica=Replica(group="echo", index=index, count=2,
                                                                 match="header.stamp"))


def test_edge_up_starts_one_merge_per_group_and_status_names_a_dead_replica(
        three_masters: tuple[Master, Master, Master], procs: Procs, tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The deployed path: a plan whose two routes are copies of one node gets one supervised
    ``fogiac.net.relay.replicas`` process; its figures reach ``fogiac status``'s rows."""
    edge, m0, m1 = three_masters
    req, rep = "/deployed/request", "/deployed/reply"
    stack = "reptest"
    bundle = new_bundle(stack)
    save_bundle(bundle, tmp_path / "edge-certs")
    ends, connect = [], {}
    for i, master in enumerate((m0, m1)):
        host_certs = tmp_path / f"r{i}-certs"
        save_pair(host_certs, "ca", bundle.ca)
        name = relay_name(stack, f"r{i}")
        save_pair(host_certs, "server", issue(bundle.ca, name, server=True, dns_names=(name,)))
        proc, (address, port) = cloud_end(procs, master, host_certs, req, rep)
        ends.append(proc)
        connect[f"r{i}"] = f"{address}:{port}"
        node(procs, master, "echo", req, rep, "--name", f"r{i}")
    plan = dataclasses.replace(compile_plan(load_manifest(EXAMPLES / "minimal.yaml")), stack=stack,
                               routes=(replica_route("r0", 0, req, rep), replica_route("r1", 1, req, rep)))
    folder = tmp_path / "edge"
    monkeypatch.setenv("PYTHONPATH", os.getcwd())
    monkeypatch.setenv("ROS_HOSTNAME", "127.0.0.1")
    assert edge_up(plan, entry=edge.uri, connect=connect, certs=tmp_path / "edge-certs", folder=folder) == []
    try:
        def figures() -> dict[str, dict]:
            return {link["host"]: link["replica"] for link in edge_links(folder, connect, plan)}

        wait_for(lambda: all(f.get("connected") for f in figures().values()), 30, "both replicas linked")
        got = run_robot(procs, edge, req, rep, 40)
        assert sorted(r["i"] for r in got) == list(range(40))
        wait_for(lambda: sum(f.get("won", 0) for f in figures().values()) == 40, 10, "the figures written")
        procs.kill(ends[0], signal.SIGKILL)
        wait_for(lambda: figures()["r0"]["health"] == "down", 30, "replica 0 reported down")
        lines = replicas_lines(edge_links(folder, connect, plan))
        assert [line for line in lines if isinstance(line, str)] == [
            "replica 1 of echo on r0 is not linked (host or its relay down)"]  # counted from 1 (issue 35, 23)
        table = lines[0]
        assert table.row_count == 2 and list(table.columns[2].cells) == ["r0", "r1"]
    finally:
        supervise.stop(folder, "relay-replicas-echo")
