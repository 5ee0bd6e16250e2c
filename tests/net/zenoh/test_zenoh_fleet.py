"""A fleet over Zenoh (issue 34): three robots' edge routers, one cloud router, a shared request/reply node.

Real routers with fogiac's rendered configs on loopback (``python -m fogiac.net.zenoh.router``); each robot's
edge router has its own certificate from the lab's CA and NO access control of its own (a robot is the
robot's: only the cloud router's rules stand between robots). Robots are ros2node stand-ins asking on
``/<robot>/plan_request`` and hearing on ``/<robot>/plan_result``; the shared node is an echo on the plain
keys behind fogiac's fleet process (``python -m fogiac.net.zenoh.fleet``).
"""

from __future__ import annotations

import json
import struct
import time
from pathlib import Path
from typing import Any

import pytest

from fogiac.net.zenoh import deploy, tls
from fogiac.net.zenoh.config import cloud_router, edge_router
from fogiac.procs import poll
from fogiac.state import write_json_atomic
from tests.net.zenoh.lab import STACK, ZenohLab, free_ports, read_events, route

zenoh = pytest.importorskip("zenoh", reason="needs eclipse-zenoh (pip install 'fogiac[ros2]')")
pytest.importorskip("zenoh_ros2_sdk", reason="needs zenoh-ros2-sdk (pip install 'fogiac[ros2]')")
pytestmark = pytest.mark.zenoh

ROBOTS = ("r1", "r2", "r3")
TYPE = "std_msgs::msg::dds_::Header_/RIHS01_x"  # type and hash chunks of a raw probe's keys


class Fleet:
    """The cloud router following its fleet file (as ``up`` runs it: ``--fleet-file``), the shared node and its
    fleet process, one edge router per robot; ``local[robot]``: the loopback port of that robot's edge router;
    ``admit``: rewrite the fleet file (the robots listed, the revoked), as ``up`` and ``robot revoke`` do."""

    def __init__(self, lab: ZenohLab, *, delay: float = 0.0, robots: tuple[str, ...] = ROBOTS) -> None:
        self.lab = lab
        self.tls_port, self.cloud_local, *edges = free_ports(2 + len(ROBOTS))
        self.host_files = lab.host_files("gpu")
        self.stats = lab.root / "cloud.stats.json"
        self.fleet = lab.root / "zenoh-fleet.json"
        self.admit(robots)
        config = cloud_router(route(self.tls_port), listen_host="127.0.0.1", tls=self.host_files,
                              local_port=self.cloud_local, robots={})
        config["id"] = deploy.router_id(STACK, "gpu")
        self.cloud = lab.router("cloud-router", config, "--stats-file", str(self.stats),
                                "--fleet-file", str(self.fleet))
        lab._start(["-m", "tests.net.zenoh.echonode", str(self.cloud_local), "--request", "/plan_request",
                    "--reply", "/plan_result", "--delay", str(delay)], "planner")
        mux = ["-m", "fogiac.net.zenoh.fleet", f"tcp/127.0.0.1:{self.cloud_local}", "--request", "/plan_request",
               "--reply", "/plan_result"]
        lab._start(mux + [a for r in ROBOTS for a in ("--robot", r)], "fleet")
        self.local = dict(zip(ROBOTS, edges, strict=True))
        for robot, port in self.local.items():
            files = lab.files(f"edge-{robot}", tls.edge_pair(lab.ca, stack=STACK, edge=robot))
            config = edge_router([("127.0.0.1", self.tls_port)], tls=files, policy=[], local_port=port)
            del config["access_control"]  # the robot's own router is the robot's to change
            config["id"] = deploy.edge_router_id(STACK, robot)
            lab.router(f"edge-{robot}", config)

    def admit(self, robots: tuple[str, ...], revoked: tuple[str, ...] = ()) -> None:
        doc = {"robots": {r: {"common_name": tls.edge_name(STACK, r), "zid": deploy.edge_router_id(STACK, r)}
                          for r in robots}, "revoked": list(revoked)}
        write_json_atomic(self.fleet, doc)

    def linked(self) -> set[str]:
        """The edge routers linked to the cloud router now (its stats, written every second)."""
        ids = {deploy.edge_router_id(STACK, r): r for r in ROBOTS}
        routers = json.loads(self.stats.read_text())["routers"] if self.stats.exists() else []
        return {ids[z] for z in routers if z in ids}

    def robot(self, robot: str) -> Path:
        return self.lab.node(robot, self.local[robot], pub=(f"/{robot}/plan_request=Header",),
                             sub=(f"/{robot}/plan_result=Header",))


def replies(out: Path) -> list[dict[str, Any]]:
    return [e for e in read_events(out) if e["event"] == "received"]


def _probe(port: int) -> Any:
    config = {"mode": "client", "connect": {"endpoints": [f"tcp/127.0.0.1:{port}"], "timeout_ms": 10000},
              "scouting": {"multicast": {"enabled": False}}}
    return zenoh.open(zenoh.Config.from_json5(json.dumps(config)))


def _request(sec: int, frame_id: str) -> bytes:
    """A CDR std_msgs/Header: encapsulation (CDR_LE), stamp, frame_id."""
    text = frame_id.encode() + b"\0"
    return b"\0\1\0\0" + struct.pack("<iII", sec, 0, len(text)) + text


def _frame_id(payload: bytes) -> str:
    (size,) = struct.unpack_from("<I", payload, 12)
    return payload[16:16 + size - 1].decode()


def _text(payload: bytes) -> str:
    try:
        return _frame_id(payload)
    except (struct.error, UnicodeDecodeError):
        return repr(payload[:64])


def ask_with_one_stamp(probes: dict[str, Any]) -> dict[str, list[tuple[str, tuple[int, int]]]]:
    """Each probe (a robot's session) sends five requests stamped alike, back to back with the others; what
    each robot heard back: (frame id, stamp) per reply, once each robot has five."""
    heard: dict[str, list[tuple[str, tuple[int, int]]]] = {robot: [] for robot in probes}
    for robot, probe in probes.items():
        probe.declare_subscriber(f"0/{robot}/plan_result/{TYPE}", lambda s, r=robot: heard[r].append(
            (_frame_id(s.payload.to_bytes()), struct.unpack_from("<iI", s.payload.to_bytes(), 4))))
    time.sleep(1)  # the subscriptions reach the cloud
    for n in range(5):
        for robot, probe in probes.items():
            probe.put(f"0/{robot}/plan_request/{TYPE}", _request(777, f"{robot} asks {n}"))
    poll(lambda: all(len(h) >= 5 for h in heard.values()) or None, timeout=30)
    return heard


def test_each_reply_reaches_only_the_robot_that_asked_also_with_equal_stamps(tmp_path: Path) -> None:
    with ZenohLab(tmp_path) as lab:
        fleet = Fleet(lab, delay=0.3)  # the node answers late: equal stamps from two robots are in flight at once
        outs = {r: fleet.robot(r) for r in ROBOTS}
        for robot, out in outs.items():
            assert poll(lambda o=out: len(replies(o)) >= 8 or None, timeout=60), f"{robot} was never answered"
        # raw requests with one stamp from r1 and r2, back to back, several rounds: each gets its own back
        probes = {r: _probe(fleet.local[r]) for r in ("r1", "r2")}
        try:
            heard = ask_with_one_stamp(probes)
            time.sleep(1)  # any stray or duplicate reply has time to arrive
        finally:
            for probe in probes.values():
                probe.close()
    for robot, got in heard.items():
        assert sorted(got) == [(f"{robot} asks {n}", (777, 0)) for n in range(5)], got
    for robot, out in outs.items():
        got = replies(out)
        assert all(e["text"].startswith(f"/{robot}/plan_request #") for e in got), got
        assert all(e["text"].endswith(f"@{e['seq']}.0") for e in got), "a robot saw a stamp it did not send"
        assert len({e["seq"] for e in got}) == len(got), f"{robot} was answered twice"
    seqs = [{e["seq"] for e in replies(out)} for out in outs.values()]
    assert seqs[0] & seqs[1] & seqs[2], "no stamp was asked by every robot"


def test_a_robot_can_neither_read_nor_publish_another_robots_keys(tmp_path: Path) -> None:
    with ZenohLab(tmp_path) as lab:
        fleet = Fleet(lab)
        victim = fleet.robot("r2")
        assert poll(lambda: len(replies(victim)) >= 3 or None, timeout=60), "r2 was never answered"
        attacker, cloud = _probe(fleet.local["r1"]), _probe(fleet.cloud_local)
        stolen: list[str] = []
        at_cloud: list[str] = []  # what the planner is asked: the fleet process's requests, none forged
        mine: list[str] = []
        try:
            # r1's own router hands r1 its own puts back; only r2's messages (its frame ids) would be stolen
            attacker.declare_subscriber("**", lambda s: stolen.append(_text(s.payload.to_bytes())))
            attacker.declare_subscriber("*/r2/**", lambda s: stolen.append(_text(s.payload.to_bytes())))
            attacker.declare_subscriber(f"0/r1/plan_result/{TYPE}", lambda s: mine.append(str(s.key_expr)))
            cloud.declare_subscriber(f"*/plan_request/{TYPE}", lambda s: at_cloud.append(_text(s.payload.to_bytes())))
            time.sleep(1)
            for n in range(10):
                attacker.put(f"0/r2/plan_result/{TYPE}", _request(n, "forged by r1"))  # into r2's replies
                attacker.put(f"0/r2/plan_request/{TYPE}", _request(n, "forged by r1"))  # as r2, to the planner
                attacker.put(f"0/plan_request/{TYPE}", _request(n, "forged by r1"))  # past the fleet process
                attacker.put(f"0/r1/plan_request/{TYPE}", _request(1000 + n, "r1 asks"))  # its own: allowed
                time.sleep(0.1)
            # control: r1's own request crossed and was answered, so the link carried what was allowed
            assert poll(lambda: len(mine) >= 10 or None, timeout=30), "r1's own requests were not answered"
            lab.wait_received(victim, "/r2/plan_result", count=len(replies(victim)) + 10)
        finally:
            attacker.close()
            cloud.close()
    assert stolen and not [t for t in stolen if "r2/" in t], stolen
    assert "r1 asks" in at_cloud and not [t for t in at_cloud if "forged" in t], at_cloud
    assert not [e for e in replies(victim) if "forged" in e["text"]]


def _as_robot(fleet: Fleet, robot: str) -> Any:
    """A session holding ``robot``'s certificate that dials the cloud router itself (a client must link)."""
    files = fleet.lab.files(f"edge-{robot}", tls.edge_pair(fleet.lab.ca, stack=STACK, edge=robot))
    config = {"mode": "client", "connect": {"endpoints": [f"tls/127.0.0.1:{fleet.tls_port}"], "timeout_ms": 3000},
              "scouting": {"multicast": {"enabled": False}},
              "transport": {"link": {"tls": {"root_ca_certificate": files.ca, "enable_mtls": True,
                                             "verify_name_on_connect": True, "connect_certificate": files.cert,
                                             "connect_private_key": files.key}}}}
    return zenoh.open(zenoh.Config.from_json5(json.dumps(config)))


def _gaps(out: Path, since: int) -> list[int]:
    """The requests from seq ``since`` on that went unanswered, up to the last one answered."""
    seqs = {e["seq"] for e in replies(out)}
    return sorted(set(range(since, max(seqs) + 1)) - seqs)


def test_robots_come_and_go_refused_by_certificate_and_the_others_lose_nothing(tmp_path: Path) -> None:
    """r3 added to the fleet file, revoked, restored, removed: each time only r3's link changes. Its certificate
    is refused within 10 s (its edge router unlinked, a session with its certificate cannot open), and r1's and
    r2's requests, sent every 100 ms throughout, are every one answered: no link of theirs dropped."""
    with ZenohLab(tmp_path) as lab:
        fleet = Fleet(lab, robots=("r1", "r2"))  # r3's edge router dials, with a certificate not admitted yet
        outs = {r: fleet.robot(r) for r in ROBOTS}
        for robot in ("r1", "r2"):
            assert poll(lambda o=outs[robot]: len(replies(o)) >= 5 or None, timeout=60), f"{robot} was never answered"
        since = {r: max(e["seq"] for e in replies(outs[r])) for r in ("r1", "r2")}
        assert not replies(outs["r3"]) and "r3" not in fleet.linked(), "a robot not in the fleet file was admitted"

        fleet.admit(ROBOTS)  # added
        assert poll(lambda: len(replies(outs["r3"])) >= 3 or None, timeout=30), "r3 was not admitted when added"
        timings = {}
        for step, robots, revoked in (("revoked", ROBOTS, ("r3",)), ("removed", ("r1", "r2"), ())):
            cut = time.monotonic()
            fleet.admit(robots, revoked)
            assert poll(lambda: "r3" not in fleet.linked() or None, timeout=10), f"r3's link stands, {step}"
            timings[step] = time.monotonic() - cut
            time.sleep(2)  # what r3's stand-in sent and heard before the cut is in its file (its writes may lag)
            asked = max(e["seq"] for e in read_events(outs["r3"]) if e["event"] == "sent")
            with pytest.raises(zenoh.ZError):  # its certificate is refused at the gate: no session opens
                _as_robot(fleet, "r3").close()
            for robot in ("r1", "r2"):  # answered on while r3 is refused; r3 is not
                lab.wait_received(outs[robot], f"/{robot}/plan_result", count=len(replies(outs[robot])) + 10)
            late = [e["seq"] for e in replies(outs["r3"]) if e["seq"] > asked]  # asked after the cut, answered
            assert late == [], f"r3 was answered on, {step}"
            fleet.admit(ROBOTS)  # restored (then added back)
            assert poll(lambda c=len(replies(outs["r3"])): len(replies(outs["r3"])) >= c + 3 or None, timeout=30), \
                f"r3 was not answered again after being {step}"
        for robot in ("r1", "r2"):
            lab.wait_received(outs[robot], f"/{robot}/plan_result", count=len(replies(outs[robot])) + 10)
            assert _gaps(outs[robot], since[robot]) == [], f"{robot} lost requests while r3 came and went"
            assert robot in fleet.linked()
        print(f"r3 unlinked {timings['revoked']:.1f} s after revoked, {timings['removed']:.1f} s after removed;"
              f" r1, r2 answered without a gap: {len(replies(outs['r1']))}, {len(replies(outs['r2']))} replies")
