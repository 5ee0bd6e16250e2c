"""Issue 34, ROS 1: a shared request/reply node's replies go back only to the robot whose request each answers.

Three robots, each its own roscore, certificate, relay edge end and client process, ask one echo node on the
cloud's master through one cloud end (the access file names the node's pair, ``match: header.stamp``). arm1
and arm2 send requests with equal stamps at once, arm3 stamps every request 0: each robot gets every one of
its replies exactly once, with the stamp it sent, and none of another robot's (told apart by the seq each
robot's requests carry). A second node on the cloud publishes replies no robot asked for: they reach nobody.
"""

from __future__ import annotations

import contextlib
import json
import sys
from pathlib import Path

import pytest

from fogiac.net.relay.fleet import ACCESS_FILE, SharedPair, write_access
from tests.fleet.fleet_support import ROBOTS, access, cloud_end, edge_end
from tests.net.relay.relay_support import Master, Proc, Procs, wait_for

pytestmark = pytest.mark.ros

NODES = Path(__file__).parents[1] / "net" / "relay" / "replica_nodes.py"
PLANNER = SharedPair("planner", frozenset({"/plan/request"}), frozenset({"/plan/reply"}), "header.stamp")
COUNT = 30
SEQ_BASE = {"arm1": 0, "arm2": 1000, "arm3": 2000}  # whose request a reply answers, whatever its stamp


def _node(procs: Procs, master: Master, *args: str) -> Proc:
    proc = procs.spawn([sys.executable, str(NODES), *args], master.env)
    wait_for(lambda: "ready" in proc.lines or proc.popen.poll() is not None, 30, f"replica node {args}")
    assert proc.popen.poll() is None, f"replica node {args} exited"
    return proc


def _replies(proc: Proc) -> list[dict]:
    return [json.loads(line) for line in proc.lines if line.startswith("{")]


def _written(path: Path, *keys: str) -> object:
    """What a stats file says under ``keys`` (None while it is not written yet, or says nothing there)."""
    try:
        found: object = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    for key in keys:
        found = found.get(key) if isinstance(found, dict) else None
    return found


def _go(asking: dict[str, Proc], go: Path) -> None:
    """Let the robots send at once, when every one is linked: their requests are in flight together."""
    wait_for(lambda: all("connected" in p.lines for p in asking.values()), 60, "every robot linked")
    go.touch()


def test_each_reply_goes_to_the_robot_that_asked(masters: tuple[Master, Master], fleet_certs: Path,
                                                 procs: Procs, tmp_path: Path) -> None:
    first, cloud_m = masters
    write_access(fleet_certs / ACCESS_FILE, access(shared=(PLANNER,)))
    robots = {"arm1": first, "arm2": procs.roscore(), "arm3": procs.roscore()}
    # The shared node is slow enough (30 ms a request, 60 requests/s arriving) that requests queue up: equal
    # stamps from arm1 and arm2, and arm3's zero stamps, are in flight together.
    _node(procs, cloud_m, "echo", "/plan/request", "/plan/reply", "--name", "planner", "--work-ms", "30")
    _node(procs, cloud_m, "echo", "/stray/request", "/plan/reply", "--name", "stray")  # answers no robot
    cloud_file = tmp_path / "relay-cloud.stats.json"
    edge_files = {name: tmp_path / f"relay-edge-planner@{name}.stats.json" for name in robots}
    with cloud_end(cloud_m, fleet_certs, stats_file=cloud_file) as cloud, contextlib.ExitStack() as stack:
        for n, (name, master) in enumerate(robots.items()):
            stack.callback(edge_end(name, master, fleet_certs, cloud, n, stats_file=edge_files[name]).stop)
        asking = {name: _node(procs, master, "robot", "/plan/request", "/plan/reply", "--count", str(COUNT),
                              "--rate", "20", "--wait", "5", "--seq-base", str(SEQ_BASE[name]), "--go",
                              str(tmp_path / "go"), *(["--zero-stamp"] if name == "arm3" else ["--base", "1000"]))
                  for name, master in robots.items()}
        _go(asking, tmp_path / "go")
        wait_for(lambda: all(_replies(p) for p in asking.values()), 60, "every robot's first reply")
        stray = _node(procs, cloud_m, "robot", "/stray/request", "/plan/reply", "--count", "10", "--rate", "20",
                      "--base", "900000", "--wait", "1")
        wait_for(lambda: all("done" in p.lines for p in (*asking.values(), stray)), 90, "every robot done")

        for name in ROBOTS:
            got = _replies(asking[name])
            assert sorted(r["i"] for r in got) == list(range(COUNT)), name  # each request answered exactly once
            assert {r["from"] for r in got} == {"planner"}, name  # no stray reply
            base = SEQ_BASE[name]
            assert sorted(r["seq"] for r in got) == list(range(base, base + COUNT)), name  # its own requests only
            assert {r["nsecs"] for r in got} == {0}, name  # the stamp it sent, never the one the node saw
        figures = cloud.reply_stats()["planner"]
        assert figures["forwarded"] == figures["answered"] == 3 * COUNT and figures["pending"] == 0
        assert figures["served"] == dict.fromkeys(ROBOTS, COUNT) and figures["undelivered"] == 0
        assert figures["restamped"] > 0  # equal stamps were in flight together
        assert figures["unmatched"] >= 1  # the stray replies, dropped
        # The cloud end's stats file has the same figures (per robot served, the strays); each robot's edge end
        # hears its own count (REPORT frames) and writes it in its stats file, which `fogiac status` reads.
        wait_for(lambda: _written(cloud_file, "replies", "planner", "served") == dict.fromkeys(ROBOTS, COUNT)
                 and _written(cloud_file, "replies", "planner", "unmatched") == figures["unmatched"], 10,
                 "the cloud end's stats file")
        wait_for(lambda: all(_written(edge_files[name], "routed") == {"served": COUNT, "undelivered": 0}
                             for name in ROBOTS), 10, "each robot's count in its edge's stats file")


def test_equal_keys_of_another_field_are_answered_in_arrival_order(masters: tuple[Master, Master],
                                                                   fleet_certs: Path, procs: Procs,
                                                                   tmp_path: Path) -> None:
    """``match: seq``, read with the definitions the robots' and the node's publishers send: arm1 and arm2 send
    the same seqs, in flight together, and each robot gets only its own replies (told apart by their stamps)."""
    first, cloud_m = masters
    grasp = SharedPair("grasp", frozenset({"/grasp/request"}), frozenset({"/grasp/reply"}), "seq")
    write_access(fleet_certs / ACCESS_FILE, access(shared=(grasp,), topics=("/grasp/request", "/grasp/reply")))
    robots = {"arm1": first, "arm2": procs.roscore()}
    bases = {"arm1": 1000, "arm2": 5000}
    _node(procs, cloud_m, "echo", "/grasp/request", "/grasp/reply", "--name", "grasp", "--work-ms", "30")
    with cloud_end(cloud_m, fleet_certs) as cloud, contextlib.ExitStack() as stack:
        for n, (name, master) in enumerate(robots.items()):
            stack.callback(edge_end(name, master, fleet_certs, cloud, n).stop)
        asking = {name: _node(procs, master, "robot", "/grasp/request", "/grasp/reply", "--count", "40",
                              "--rate", "50", "--wait", "8", "--base", str(bases[name]), "--go", str(tmp_path / "go"))
                  for name, master in robots.items()}
        _go(asking, tmp_path / "go")
        wait_for(lambda: all("done" in p.lines for p in asking.values()), 90, "both robots done")
        for name in robots:
            got = _replies(asking[name])
            assert sorted(r["i"] for r in got) == list(range(40)), name  # its own stamps, each once
            assert sorted(r["seq"] for r in got) == list(range(40)), name
        figures = cloud.reply_stats()["grasp"]
        assert figures["forwarded"] == figures["answered"] == 80 and figures["restamped"] == 0
        assert figures["queued"] > 0  # equal seqs were in flight together
