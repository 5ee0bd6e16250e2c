"""A replicated node over Zenoh: real routers with fogiac's rendered configs (mutual TLS, access control),
each replica's host renaming its node's keys under its prefix, the edge's merge handing the robot the
first reply per request. The "nodes" are zenoh sessions putting CDR messages whose first field is a
std_msgs/Header, with rmw_zenoh's key layout. Asserts on counts and on who won, never on time."""

from __future__ import annotations

import dataclasses
import json
import struct
import sys
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

import pytest

from fogiac.hostmodel import Layout, Where
from fogiac.manifest.schema import load_manifest
from fogiac.net.zenoh.config import access_control, edge_access_control, replica_keys_prefix
from fogiac.net.zenoh.deploy import edge_links, replica_merges, replica_service
from fogiac.net.zenoh.errors import ZenohError
from fogiac.net.zenoh.replicas import CloudPrefix, EdgeMerge, replica_prefix
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Replica, Route
from fogiac.procs import poll
from fogiac.provision import supervise
from fogiac.provision.runtimes.native import NATIVE
from tests.net.zenoh.lab import ZenohLab, free_ports

zenoh = pytest.importorskip("zenoh", reason="needs eclipse-zenoh (pip install 'fogiac[ros2]')")
pytestmark = pytest.mark.zenoh

REQ, REP = "/plan_req", "/plan_rep"
EXAMPLES = Path(__file__).parents[3] / "examples"
TYPE = "std_msgs::msg::dds_::Header_/RIHS01_abc"  # rmw_zenoh's key: <domain>/<topic>/<type>/<hash>
REQ_KEY, REP_KEY = f"0/plan_req/{TYPE}", f"0/plan_rep/{TYPE}"


def header(sec: int, frame: str) -> bytes:
    """A CDR little-endian std_msgs/Header: encapsulation, int32 sec, uint32 nanosec, string frame_id."""
    text = frame.encode() + b"\0"
    return b"\x00\x01\x00\x00" + struct.pack("<iiI", sec, 0, len(text)) + text


def session(port: int) -> Any:
    return zenoh.open(zenoh.Config.from_json5(json.dumps({
        "mode": "client", "connect": {"endpoints": [f"tcp/127.0.0.1:{port}"]},
        "scouting": {"multicast": {"enabled": False}}})))


def replica_route(host: str, index: int, port: int) -> Route:
    return Route(host=host, connect_via="loopback", port=port, auto=False, to_cloud=(REQ,), to_edge=(REP,), listed=(),
                 compression=(), queue_size=2, replica=Replica("planner", index, 2, "header.stamp"))


def test_a_replica_only_lets_its_prefixed_keys_cross() -> None:
    rt = replica_route("r1", 1, 7448)  # the second replica: numbered 2 on the wire, as shown (issue 35, 23)
    assert replica_keys_prefix(rt) == replica_prefix("planner", 1) + "/" == "fogiac/replica/planner/2/"
    rules = {r["id"]: r["key_exprs"] for r in access_control(rt, edge_name="edge")["rules"]}
    assert rules["edge-data-in"] == rules["edge-interest-out"] == ["fogiac/replica/planner/2/*/plan_req/*/*"]
    assert rules["edge-data-out"] == rules["edge-interest-in"] == ["fogiac/replica/planner/2/*/plan_rep/*/*"]
    # the edge router's mirror image: from that host only its prefixed replies, to it only its prefixed requests
    edge = {r["id"]: r["key_exprs"] for r in edge_access_control([("r1-cert", rt)])["rules"]}
    assert edge["cloud0-data-in"] == ["fogiac/replica/planner/2/*/plan_rep/*/*"]
    assert edge["cloud0-data-out"] == ["fogiac/replica/planner/2/*/plan_req/*/*"]


def test_a_topic_renamed_both_ways_is_refused_before_it_loops() -> None:
    with pytest.raises(ZenohError, match="/a: a replica's topic goes one way"):
        CloudPrefix("tcp/127.0.0.1:1", "fogiac/replica/g/0", to_cloud=("/a",), to_edge=("/a", "/b"))


def test_every_request_answered_once_while_a_replica_dies(tmp_path: Path) -> None:
    with ZenohLab(tmp_path) as lab:
        edge_local, *ports = free_ports(5)
        tls_ports, locals_ = ports[:2], ports[2:]
        routes = tuple(replica_route(f"r{i}", i, tls_ports[i]) for i in range(2))
        routers = [lab.router(f"cloud-{i}", lab.cloud_config(routes[i], local_port=locals_[i])) for i in range(2)]
        lab.router("edge-router", lab.edge_config([("127.0.0.1", p) for p in tls_ports], local_port=edge_local,
                                                  routes=routes))
        opened: list[Any] = []
        ends: list[Any] = []
        try:
            for i in range(2):  # each replica: its node answering on plain keys, and the prefix process
                node = session(locals_[i])
                opened.append(node)

                def answer(sample: Any, node: Any = node, name: str = f"r{i}") -> None:
                    sec = struct.unpack_from("<i", sample.payload.to_bytes(), 4)[0]
                    node.put(REP_KEY, header(sec, name))

                node.declare_subscriber(REQ_KEY, answer)
                ends.append(CloudPrefix(f"tcp/127.0.0.1:{locals_[i]}", replica_prefix("planner", i),
                                        to_cloud=(REQ,), to_edge=(REP,)))
            merge = EdgeMerge(f"tcp/127.0.0.1:{edge_local}", "planner", [(0, "r0"), (1, "r1")], to_cloud=(REQ,),
                              to_edge=(REP,), silent_after=1.0)
            ends.append(merge)
            for end in ends:
                end.start()
            robot = session(edge_local)
            opened.append(robot)
            got: list[tuple[int, str]] = []
            lock = threading.Lock()

            def received(sample: Any) -> None:
                data = sample.payload.to_bytes()
                with lock:
                    got.append((struct.unpack_from("<i", data, 4)[0], data[16:-1].decode()))

            robot.declare_subscriber("*/plan_rep/*/*", received)
            # until the path is up, a probe request (stamp 0) is answered
            probes: list[None] = []  # each stamped 0: each is a request of its own, answered once if it got through
            assert poll(lambda: probes.append(robot.put(REQ_KEY, header(0, "robot"))) or (got or None), timeout=30,
                        interval=0.5)
            time.sleep(1.0)  # late probe replies arrive before the counted run
            with lock:
                got.clear()
            for sec in range(1, 61):
                robot.put(REQ_KEY, header(sec, "robot"))
                if sec == 20:
                    lab.stop(routers[0], kill=True)  # replica 0's host dies mid-run
                time.sleep(0.05)
            poll(lambda: len({s for s, _ in got}) >= 60 or None, timeout=30)
            time.sleep(1.0)  # a duplicate would have arrived by now
            stats = merge.stats()
        finally:
            for end in ends:
                end.stop()
            for s in opened:
                s.close()
    assert sorted(s for s, _ in got) == list(range(1, 61))  # each request answered exactly once
    assert Counter(name for sec, name in got if sec > 25) == {"r1": 35}
    r0, r1 = stats["replicas"]
    assert r0["health"] == "silent" and r1["health"] == "ok"
    assert stats["duplicates_dropped"] > 0  # both answered before the kill: the copies never reached the robot


def test_the_deployed_merge_answers_once_and_its_figures_reach_status(tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """``edge_up``'s part for replicas (:func:`replica_merges`) starts the merge as a supervised process;
    ``edge_links`` hands each host its replica's figures; the cloud side runs the command
    :func:`replica_service` renders for a replica's host."""
    with ZenohLab(tmp_path) as lab:
        edge_local, *ports = free_ports(5)
        tls_ports, locals_ = ports[:2], ports[2:]
        routes = tuple(replica_route(f"r{i}", i, tls_ports[i]) for i in range(2))
        for i, rt in enumerate(routes):
            lab.router(f"cloud-{i}", lab.cloud_config(rt, local_port=locals_[i]))
        lab.router("edge-router", lab.edge_config([("127.0.0.1", p) for p in tls_ports], local_port=edge_local,
                                                  routes=routes))
        plan = dataclasses.replace(compile_plan(load_manifest(EXAMPLES / "ros2-zenoh.yaml")), routes=routes)
        opened: list[Any] = []
        ends: list[Any] = []
        folder = tmp_path / "edge"
        monkeypatch.setenv("PYTHONPATH", str(Path.cwd()))
        connect = {"r0": f"127.0.0.1:{tls_ports[0]}", "r1": f"127.0.0.1:{tls_ports[1]}"}
        try:
            for i in range(2):
                node = session(locals_[i])
                opened.append(node)
                node.declare_subscriber(REQ_KEY, lambda s, node=node, name=f"r{i}": node.put(
                    REP_KEY, header(struct.unpack_from("<i", s.payload.to_bytes(), 4)[0], name)))
                where = Where(layout=Layout(str(tmp_path / f"host-r{i}")), runtime=NATIVE, master_port=locals_[i],
                              relay_port=tls_ports[i], ros_address="127.0.0.1", python=sys.executable,
                              code_root=str(Path.cwd()))
                command = replica_service(plan, plan.hosts[0], where, routes[i])
                assert command is not None
                assert f"fogiac.net.zenoh.replicas cloud tcp/127.0.0.1:{locals_[i]} --prefix" in command.script
                prefix = command.script.split(" --prefix ")[1].split()[0]
                assert prefix == replica_prefix("planner", i)
                ends.append(CloudPrefix(f"tcp/127.0.0.1:{locals_[i]}", prefix, to_cloud=(REQ,), to_edge=(REP,)))
                ends[-1].start()
            assert replica_merges(plan, entry=f"tcp/127.0.0.1:{edge_local}", connect=connect, folder=folder) == []
            robot = session(edge_local)
            opened.append(robot)
            got: list[int] = []
            robot.declare_subscriber("*/plan_rep/*/*", lambda s: got.append(
                struct.unpack_from("<i", s.payload.to_bytes(), 4)[0]))
            probes: list[None] = []  # each stamped 0: each is a request of its own, answered once if it got through
            assert poll(lambda: probes.append(robot.put(REQ_KEY, header(0, "robot"))) or (got or None), timeout=30,
                        interval=0.5)
            time.sleep(1.0)
            got.clear()
            for sec in range(1, 31):
                robot.put(REQ_KEY, header(sec, "robot"))
                time.sleep(0.03)

            def figures() -> dict[str, Any] | None:
                found = {link["host"]: link["replica"] for link in edge_links(plan, folder=folder, connect=connect)}
                return found if sum(f.get("won", 0) for f in found.values()) >= 31 else None

            found = poll(figures, timeout=20)
        finally:
            supervise.stop(folder, "zenoh-replicas-planner")
            for end in ends:
                end.stop()
            for s in opened:
                s.close()
    assert sorted(got) == list(range(1, 31))
    assert found is not None and 31 <= found["r0"]["won"] + found["r1"]["won"] <= 30 + len(probes)
    assert {f["health"] for f in found.values()} == {"ok"}
    assert min(f["answers"] for f in found.values()) >= 30  # both answered every request (and the probes they got)


def test_a_match_the_zenoh_merge_cannot_read_starts_no_merge(tmp_path: Path) -> None:
    """Issue 35 (8): a reply_match other than header.stamp was merged by bytes 4..12 whatever it said (a CDR
    request_id gave 1 answer of 5). validate refuses it; a plan made otherwise gets a note and no merge."""
    routes = tuple(dataclasses.replace(replica_route(f"r{i}", i, 1), replica=Replica("planner", i, 2, "request_id"))
                   for i in range(2))
    plan = dataclasses.replace(compile_plan(load_manifest(EXAMPLES / "ros2-zenoh.yaml")), routes=routes)
    notes = replica_merges(plan, entry="tcp/127.0.0.1:1", connect={"r0": "a:1", "r1": "b:1"}, folder=tmp_path)
    assert notes == ["node planner: not merged: over Zenoh replies are matched by header.stamp only, not 'request_id'"]
    assert list(tmp_path.iterdir()) == []
