"""A fleet over Zenoh (issue 34): three robots' edge routers, one cloud router, a shared request/reply node.

Real routers with fogiac's rendered configs on loopback (``python -m fogiac.net.zenoh.router``); each robot's
edge router has its own certificate from the lab's CA and NO access control of its own (a robot is the
robot's: only the cloud router's rules stand between robots). Robots are ros2node stand-ins asking on
``/<robot>/plan_request`` and hearing on ``/<robot>/plan_result``; the shared node is an echo on the plain
keys behind fogiac's fleet process (``python -m fogiac.net.zenoh.fleet``). The cloud router follows its fleet
file as ``up`` runs it: its TLS gate admits a robot's certificate only while the file names it, unrevoked.

One fleet for the module (its routers, planner and stand-ins start once; each test leaves every robot
admitted): the stand-ins' files hold every reply of the whole run, so "answered once, to its own robot only"
is checked over everything the other tests did too.
"""

from __future__ import annotations

import json
import socket
import ssl
import struct
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from fogiac.certs import new_ca
from fogiac.net.zenoh import deploy, tls
from fogiac.net.zenoh.config import TlsFiles, cloud_router, edge_router
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
        self.outs: dict[str, Path] = {}
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
        self.files = {r: lab.files(f"edge-{r}", tls.edge_pair(lab.ca, stack=STACK, edge=r)) for r in ROBOTS}
        for robot, port in self.local.items():
            files = self.files[robot]
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


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    """The module's fleet, every robot admitted and answered; the planner answers late (0.3 s), so equal stamps
    from several robots are in flight at once. ``fleet.outs[robot]``: that robot's stand-in's file."""
    with ZenohLab(tmp_path_factory.mktemp("zfleet")) as lab:
        made = Fleet(lab, delay=0.3)
        made.outs = {r: made.robot(r) for r in ROBOTS}
        for robot, out in made.outs.items():
            assert poll(lambda o=out: len(replies(o)) >= 3 or None, timeout=60), f"{robot} was never answered"
        yield made


def test_each_reply_reaches_only_the_robot_that_asked_also_with_equal_stamps(fleet: Fleet) -> None:
    outs = fleet.outs
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


def test_a_robot_can_neither_read_nor_publish_another_robots_keys(fleet: Fleet) -> None:
    lab, victim = fleet.lab, fleet.outs["r2"]
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


def _as_robot(fleet: Fleet, robot: str, *, timeout_ms: int = 10000) -> Any:
    """A Zenoh session holding ``robot``'s certificate that dials the cloud router itself (a client must link)."""
    files = fleet.files[robot]
    config = {"mode": "client", "connect": {"endpoints": [f"tls/127.0.0.1:{fleet.tls_port}"], "timeout_ms": timeout_ms},
              "scouting": {"multicast": {"enabled": False}},
              "transport": {"link": {"tls": {"root_ca_certificate": files.ca, "enable_mtls": True,
                                             "verify_name_on_connect": True, "connect_certificate": files.cert,
                                             "connect_private_key": files.key}}}}
    return zenoh.open(zenoh.Config.from_json5(json.dumps(config)))


def tls_link(address: str, files: TlsFiles | None, *, ca: str, version: ssl.TLSVersion = ssl.TLSVersion.TLSv1_3,
             silent_s: float = 0.5) -> str:
    """A plain TLS client at a cloud router's ``HOST:PORT`` (``files``: the client certificate, None for none), as far
    as what the gate does with it: "open" (the link stands, silent: a Zenoh router waits for the client to
    speak first), "closed" (it closed the link after the handshake) or "handshake refused". Zenoh itself closes
    a link that never speaks after its accept timeout (10 s): so "closed" is looked for in ``silent_s`` well
    under that (the gate closes a refused link at once)."""
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    context.load_verify_locations(ca)  # and the host's certificate is checked for the address dialed
    context.minimum_version = context.maximum_version = version
    if files is not None:
        context.load_cert_chain(files.cert, files.key)
    host, _, port = address.rpartition(":")
    with socket.create_connection((host, int(port)), timeout=10) as raw:
        try:
            link = context.wrap_socket(raw, server_hostname=host)
        except (ssl.SSLError, ConnectionError):
            return "handshake refused"
        with link:
            link.settimeout(silent_s)
            try:  # TLS 1.3: the server checks the client's certificate after the client's handshake ends
                got = link.recv(1)
            except TimeoutError:
                return "open"
            except (ssl.SSLError, ConnectionError):
                return "closed"
            return "closed" if got == b"" else f"sent {got!r}"


def test_the_gate_holds_mutual_tls_1_3_to_the_stacks_ca(fleet: Fleet) -> None:
    """The gate in front of the robots' port is no weaker than Zenoh's own TLS link: an admitted robot's
    certificate links (and nothing is sent it unasked); TLS 1.2, no client certificate, or a robot's name
    signed by another CA are refused."""
    address, ca, r1 = f"127.0.0.1:{fleet.tls_port}", fleet.host_files.ca, fleet.files["r1"]
    assert tls_link(address, r1, ca=ca) == "open"
    assert tls_link(address, r1, ca=ca, version=ssl.TLSVersion.TLSv1_2) == "handshake refused"
    assert tls_link(address, None, ca=ca, silent_s=5) in {"closed", "handshake refused"}
    forged = fleet.lab.files("forged-r1", tls.edge_pair(new_ca("not the stack's CA"), stack=STACK, edge="r1"))
    assert tls_link(address, forged, ca=ca, silent_s=5) in {"closed", "handshake refused"}


def _gaps(out: Path, since: int) -> list[int]:
    """The requests from seq ``since`` on that went unanswered, up to the last one answered."""
    seqs = {e["seq"] for e in replies(out)}
    return sorted(set(range(since, max(seqs) + 1)) - seqs)


def _sent(out: Path) -> int:
    return max(e["seq"] for e in read_events(out) if e["event"] == "sent")


def test_robots_come_and_go_refused_by_certificate_and_the_others_lose_nothing(fleet: Fleet) -> None:
    """r3 revoked, restored, removed, added back (the fleet file rewritten, as ``robot revoke|restore`` and
    ``up`` do): each time only r3's link changes. Its certificate is refused within 10 s: its edge router
    unlinked, a TLS link with its certificate closed after the handshake, a Zenoh session with it unable to
    open, its requests unanswered; and r1's and r2's requests, sent every 100 ms throughout, are every one
    answered: no link of theirs dropped."""
    lab, outs = fleet.lab, fleet.outs
    address, ca, r3 = f"127.0.0.1:{fleet.tls_port}", fleet.host_files.ca, fleet.files["r3"]
    since = {r: max(e["seq"] for e in replies(outs[r])) for r in ("r1", "r2")}
    timings = {}
    try:
        for step, robots, revoked in (("revoked", ROBOTS, ("r3",)), ("removed", ("r1", "r2"), ())):
            assert poll(lambda: "r3" in fleet.linked() or None, timeout=30), f"r3 not linked before being {step}"
            cut = time.monotonic()
            fleet.admit(robots, revoked)
            assert poll(lambda: "r3" not in fleet.linked() or None, timeout=10), f"r3's link stands, {step}"
            timings[step] = time.monotonic() - cut
            asked = _sent(outs["r3"])  # the stats lag the cut: r3's requests from here on went out unlinked
            assert tls_link(address, r3, ca=ca, silent_s=5) == "closed"  # refused by its certificate
            assert tls_link(address, fleet.files["r1"], ca=ca) == "open"  # the gate's other robots are not
            if step == "revoked":  # a real Zenoh session with r3's certificate: no link, so no session
                with pytest.raises(zenoh.ZError):
                    _as_robot(fleet, "r3", timeout_ms=1500).close()
            else:  # r1 and r2 answered on while r3 is refused (a gap is looked for at the end)
                for robot in ("r1", "r2"):
                    lab.wait_received(outs[robot], f"/{robot}/plan_result", count=len(replies(outs[robot])) + 10)
            late = [e["seq"] for e in replies(outs["r3"]) if e["seq"] > asked]  # asked after the cut, answered
            assert late == [], f"r3 was answered on, {step}"
            fleet.admit(ROBOTS)  # restored (then added back)
            count = len(replies(outs["r3"]))
            assert poll(lambda c=count: len(replies(outs["r3"])) >= c + 3 or None, timeout=30), \
                f"r3 was not answered again after being {step}"
    finally:
        fleet.admit(ROBOTS)  # the module's other tests find every robot admitted
    for robot in ("r1", "r2"):
        lab.wait_received(outs[robot], f"/{robot}/plan_result", count=len(replies(outs[robot])) + 5)
        assert _gaps(outs[robot], since[robot]) == [], f"{robot} lost requests while r3 came and went"
        assert robot in fleet.linked()
    assert f"refused a link from {tls.edge_name(STACK, 'r3')}" in (lab.root / "cloud-router.log").read_text()
    print(f"r3 unlinked {timings['revoked']:.1f} s after revoked, {timings['removed']:.1f} s after removed;"
          f" r1, r2 answered without a gap: {len(replies(outs['r1']))}, {len(replies(outs['r2']))} replies")
