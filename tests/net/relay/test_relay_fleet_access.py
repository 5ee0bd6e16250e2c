"""The fleet access file's rules (``fogiac.net.relay.fleet``): namespaces, shared topics, revocation, and a
file that stops parsing (the last good rules stay; one that never parsed links no robot), and the shared nodes'
request/reply pairs whose replies are routed."""

from __future__ import annotations

import json
import threading
from pathlib import Path

import pytest

from fogiac.net.relay.fleet import (
    ACCESS_FILE,
    AccessError,
    AccessWatch,
    FleetAccess,
    Robot,
    SharedPair,
    read_access,
    write_access,
)
from fogiac.net.relay.graph import GraphState

ARM1, ARM2 = Robot("arm1", "arm1.edge.lab.fogiac", frozenset({"/plan/request"})), Robot("arm2", "arm2.edge.lab.fogiac")
RULES = FleetAccess({ARM1.identity: ARM1, ARM2.identity: ARM2}, frozenset())


def test_a_robot_may_use_its_namespace_and_its_shared_topics_only() -> None:
    assert RULES.allows(ARM1.identity, "/arm1/scan") and RULES.allows(ARM1.identity, "/plan/request")
    assert not RULES.allows(ARM1.identity, "/arm2/scan") and not RULES.allows(ARM2.identity, "/plan/request")
    assert not RULES.allows(ARM1.identity, "/arm1") and not RULES.allows(ARM1.identity, "/arm10/scan")
    assert not RULES.allows("stranger.fogiac", "/arm1/scan")
    graph = GraphState({"/arm1/a": frozenset({"/n"}), "/arm2/a": frozenset({"/n"})},
                       {"/plan/request": frozenset({"/planner"})}, {"/arm1/a": "std_msgs/String", "/arm2/a": "x/Y"})
    seen = RULES.visible(ARM1.identity, graph)
    assert set(seen.publishers) == {"/arm1/a"} and set(seen.subscribers) == {"/plan/request"}
    assert seen.types == {"/arm1/a": "std_msgs/String"}


def test_a_shared_nodes_topics_go_one_way() -> None:
    pair = SharedPair("planner", frozenset({"/plan/request"}), frozenset({"/plan/reply"}))
    arm1 = Robot("arm1", "arm1.edge.lab.fogiac", frozenset({"/plan/request", "/plan/reply"}))
    rules = FleetAccess({arm1.identity: arm1}, frozenset(), (pair,))
    assert rules.allows(arm1.identity, "/plan/request", "out") and rules.allows(arm1.identity, "/plan/reply", "in")
    assert not rules.allows(arm1.identity, "/plan/request", "in")
    assert not rules.allows(arm1.identity, "/plan/reply", "out")
    assert rules.allows(arm1.identity, "/arm1/scan", "in") and rules.allows(arm1.identity, "/arm1/scan", "out")
    assert FleetAccess({arm1.identity: arm1}).allows(arm1.identity, "/plan/request", "in")  # not named: both ways


def test_revoked_robot_is_no_robot(tmp_path: Path) -> None:
    path = tmp_path / ACCESS_FILE
    write_access(path, FleetAccess(RULES.robots, frozenset({"arm2"})))
    assert path.stat().st_mode & 0o777 == 0o600
    rules = read_access(path)
    assert rules is not None and rules == FleetAccess(RULES.robots, frozenset({"arm2"}))
    assert rules.robot(ARM2.identity) is None and not rules.allows(ARM2.identity, "/arm2/scan")
    assert rules.robot(ARM1.identity) == ARM1


def test_the_watch_follows_the_file_and_keeps_good_rules_over_a_bad_file(tmp_path: Path) -> None:
    path = tmp_path / ACCESS_FILE
    seen: list[FleetAccess | None] = []
    watch = AccessWatch(path, seen.append)
    assert watch.rules is None and seen == [None]  # no file: a single edge's rules
    path.write_text("{not json")
    watch.reload()
    assert watch.rules == FleetAccess()  # a fleet file that never parsed: no robot is linked
    write_access(path, RULES)
    stop = threading.Event()
    thread = threading.Thread(target=watch.run, args=(stop,), daemon=True)
    thread.start()
    try:
        for _ in range(50):
            if watch.rules == RULES:
                break
            stop.wait(0.1)
        assert watch.rules == RULES  # picked up by the poll, no reload asked for
    finally:
        stop.set()
        thread.join(5)
    path.write_text('{"robots": {"arm1": {"identity": 3}}}')
    watch.reload()
    assert watch.rules == RULES and seen[-1] == RULES  # the last good rules stay


def test_the_shared_nodes_pairs_round_trip_and_a_bad_pair_is_named(tmp_path: Path) -> None:
    path = tmp_path / ACCESS_FILE
    pairs = (SharedPair("planner", frozenset({"/plan/request"}), frozenset({"/plan/reply"})),
             SharedPair("map", frozenset({"/map/ask"}), frozenset({"/map/full"}), None))
    write_access(path, FleetAccess(RULES.robots, frozenset(), pairs))
    assert read_access(path) == FleetAccess(RULES.robots, frozenset(), pairs)
    write_access(path, RULES)
    assert "shared" not in json.loads(path.read_text())  # a fleet without shared nodes: the file as before
    robots = FleetAccess(RULES.robots).to_json()["robots"]
    bad = {
        "'shared' must be a list": "no",
        r"shared\[0\] needs a 'node' string": [{"requests": ["/a"], "replies": ["/b"]}],
        r"shared\[0\] \(p\): 'replies' must be a non-empty list of absolute topic names":
            [{"node": "p", "requests": ["/a"], "replies": ["b"]}],
        r"shared\[0\] \(p\): 'match' must be a dotted field path or null":
            [{"node": "p", "requests": ["/a"], "replies": ["/b"], "match": ".."}],
        r"topic /b belongs to two shared nodes' pairs \(p, q\)":
            [{"node": "p", "requests": ["/a"], "replies": ["/b"]},
             {"node": "q", "requests": ["/b"], "replies": ["/c"]}],
    }
    for message, shared in bad.items():
        path.write_text(json.dumps({"robots": robots, "shared": shared}))
        with pytest.raises(AccessError, match=f"^{path}: {message}"):
            read_access(path)
