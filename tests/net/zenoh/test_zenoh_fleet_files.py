"""Issue 34, ROS 2: what ``up`` renders for a Zenoh fleet, as pure functions, and how the router reads it.

The host's fleet file (each robot by its certificate's name and router id, the revoked ones, the shared pairs
with their robots), a router config and command that name no robot (so a robot added changes no service), the
fleet process per shared pair, each robot's edge router rules (its namespace only), a router that reads a
broken fleet file keeps no robot it was not given, and the robots' fronts opened together, all or none. The
running parts: ``tests/fleet/test_fleet_zenoh_local.py``.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from fogiac.hostmodel import Layout, Where
from fogiac.manifest.schema import parse_manifest
from fogiac.net.zenoh import deploy, tls
from fogiac.net.zenoh.config import TlsFiles, cloud_router, edge_router, fleet_access_control
from fogiac.net.zenoh.gate import FleetFile, FleetRouter, front_access_control, front_id, read_fleet, split_config
from fogiac.plan import fleet
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Plan
from fogiac.provision.runtimes.native import NATIVE
from tests.net.zenoh.lab import free_ports, route

FLEET = """name: lab
ros: {distro: jazzy}
cloud: {provider: local}
robots:
  - {name: r1, zenoh_router: "tcp/127.0.0.1:7451"}
  - {name: r2, zenoh_router: "tcp/127.0.0.1:7452"}
nodes:
  - name: planner
    machine: t3.micro
    command: [sleep, "3600"]
    topics: {in: [/plan_request], out: [/plan_result, /r2/status]}
  - name: grasp
    machine: t3.micro
    command: [sleep, "3600"]
    topics: {in: [/grasp/request], out: [/grasp/reply]}
    serve: [r1]
"""


def _plan(text: str = FLEET) -> Plan:
    return compile_plan(parse_manifest(text, base=Path.cwd()), target="local")


def test_the_fleet_file_names_each_robot_its_revocations_and_the_shared_pairs() -> None:
    plan = _plan()
    spec = plan.hosts[0]
    ((name, body, mode),) = deploy.fleet_files(plan, spec, revoked=("r2", "gone"))
    assert (name, mode) == ("zenoh-fleet.json", 0o600)
    doc = json.loads(body)
    assert doc["robots"] == {r: {"common_name": tls.edge_name(plan.stack, r),
                                 "zid": deploy.edge_router_id(plan.stack, r)} for r in ("r1", "r2")}
    assert doc["revoked"] == ["r2"]  # a name no longer in robots: is no one's
    # the planner's plain topics are its pair; /r2/status is r2's own namespace, never a pair's reply
    assert [s for s in doc["shared"] if s["node"] == "planner"] == [
        {"node": "planner", "requests": ["/plan_request"], "replies": ["/plan_result"], "robots": ["r1", "r2"]}]
    (host,) = [h for h in plan.hosts if h.name == plan.node("grasp").host]
    ((_, body, _),) = deploy.fleet_files(plan, host, revoked=())
    assert [s for s in json.loads(body)["shared"] if s["node"] == "grasp"] == [
        {"node": "grasp", "requests": ["/grasp/request"], "replies": ["/grasp/reply"], "robots": ["r1"]}]


def test_the_plan_names_each_robots_own_edge_router_certificate() -> None:
    plan = _plan()
    assert [r["certificate"] for r in fleet.robots(plan) or []] == [tls.edge_name(plan.stack, r) for r in ("r1", "r2")]


def test_one_robot_writes_no_fleet_file_and_keeps_its_router_as_before() -> None:
    one = FLEET.split("robots:")[0] + 'edge: {zenoh_router: "tcp/127.0.0.1:7451"}\nnodes:' + FLEET.split("nodes:")[1]
    plan = _plan(one.replace("    serve: [r1]\n", ""))
    assert deploy.fleet_files(plan, plan.hosts[0], revoked=()) == ()


def test_a_fleets_router_command_and_config_name_no_robot(tmp_path: Path) -> None:
    """A robot added or revoked must change no service's script or files, or provisioning would restart it."""
    plan = _plan()
    three = _plan(FLEET.replace('  - {name: r2, zenoh_router: "tcp/127.0.0.1:7452"}\n',
                                '  - {name: r2, zenoh_router: "tcp/127.0.0.1:7452"}\n'
                                '  - {name: r3, zenoh_router: "tcp/127.0.0.1:7453"}\n'))
    where = Where(layout=Layout(str(tmp_path / "host")), runtime=NATIVE, master_port=17447, relay_port=7448,
                  ros_address="127.0.0.1", python=sys.executable, code_root=str(Path.cwd()))
    two = [(s.script, s.files) for s in deploy.host_services(plan, plan.hosts[0], where, certs=tmp_path / "c")]
    more = [(s.script, s.files) for s in deploy.host_services(three, three.hosts[0], where, certs=tmp_path / "c")]
    assert two == more
    assert "--fleet-file" in two[0][0] and "--edge-id" not in two[0][0]
    (mux,) = [s for s in deploy.link_services(three, three.hosts[0], where) if s.name == "zenoh-fleet-planner"]
    assert mux == next(s for s in deploy.link_services(plan, plan.hosts[0], where) if s.name == "zenoh-fleet-planner")
    assert "--node planner --request /plan_request --reply /plan_result" in mux.script


def test_a_robots_edge_router_lets_the_cloud_reach_its_namespace_only() -> None:
    files = TlsFiles(ca="ca.pem", cert="edge.pem", key="edge.key")
    config = edge_router([("127.0.0.1", 7448)], tls=files, policy=[("gpu.router.lab.fogiac", route(7448))],
                         local_port=7451, robot="r1")
    acl = config["access_control"]
    (cloud,) = [s for s in acl["subjects"] if s["id"] == "cloud"]
    assert cloud["cert_common_names"] == ["gpu.router.lab.fogiac"]
    keys = {k for rule in acl["rules"] if rule["id"].startswith("cloud-") for k in rule["key_exprs"]}
    assert "*/r1/**" in keys and not [k for k in keys if "r1" not in k]  # nothing outside /r1/..., no listed topic


def test_the_router_reads_its_fleet_file_and_refuses_one_it_cannot(tmp_path: Path) -> None:
    fleet = tmp_path / "zenoh-fleet.json"

    def rules(doc: FleetFile) -> list[str]:
        return [s["id"] for s in fleet_access_control(doc.robots, revoked=doc.revoked)["subjects"]]

    doc = read_fleet(fleet)  # no file yet: no robot gets anything
    assert rules(doc) == ["host-nodes"] and doc.admitted == {} and doc.edges == []
    fleet.write_text(json.dumps({"robots": {"r1": {"common_name": "r1.cn", "zid": "aa"},
                                            "r2": {"common_name": "r2.cn", "zid": "bb"}}, "revoked": ["r2"]}))
    doc = read_fleet(fleet)
    assert rules(doc) == ["host-nodes", "robot-r1"] and doc.admitted == {"r1.cn": "r1"} and doc.edges == ["aa"]
    fleet.write_text('{"robots": ["r1"]')  # half written: the router keeps the robots it has (it catches this)
    with pytest.raises(ValueError):
        read_fleet(fleet)
    for shape in ('{"robots": ["r1"]}', '["r1"]', '{"robots": {"r1": {"zid": "aa"}}}'):
        fleet.write_text(shape)
        with pytest.raises(ValueError, match="robots is not a mapping"):
            read_fleet(fleet)


def test_a_robots_front_lets_its_gate_link_cross_its_namespace_only_and_its_id_is_fixed() -> None:
    """Behind the TLS gate (fogiac.net.zenoh.gate) each robot's own router: the link that comes in on the gate's
    Unix socket may cross only ``*/r1/**`` and its tokens, the core's loopback link anything; and the id the
    robot's edge sees is fixed per host and robot, which ``status`` reads as the robot's link."""
    acl = front_access_control("r1")
    subjects = {s["id"]: s for s in acl["subjects"]}
    assert subjects["robot"] == {"id": "robot", "link_protocols": ["unixsock-stream"]}
    assert subjects["core"] == {"id": "core", "link_protocols": ["tcp"], "interfaces": ["lo"]}
    (robot,) = [p for p in acl["policies"] if p["subjects"] == ["robot"]]
    keys = {k for rule in acl["rules"] if rule["id"] in robot["rules"] for k in rule["key_exprs"]}
    assert acl["default_permission"] == "deny" and "*/r1/**" in keys and not [k for k in keys if "%r1%" not in k
                                                                                 and not k.startswith("*/r1/")]
    core = deploy.router_id("lab", "gpu")
    assert front_id(core, "r1") == front_id(core, "r1") != front_id(core, "r2") != core
    plan = _plan()
    host, edge = plan.hosts[0].name, plan.edges[0]
    assert deploy.linked_id(plan, host, edge) == front_id(deploy.router_id(plan.stack, host), edge.name)


def test_the_gate_takes_its_address_and_files_from_the_rendered_config_and_refuses_a_config_without() -> None:
    files = TlsFiles(ca="ca.pem", cert="server.pem", key="server.key")
    config = cloud_router(route(7448), listen_host="10.0.0.5", tls=files, robots={}, local_port=7447)
    core, address, pem, local = split_config(config)
    assert address == ("10.0.0.5", 7448) and pem == {"ca": "ca.pem", "cert": "server.pem", "key": "server.key"}
    assert core["listen"]["endpoints"] == ["tcp/127.0.0.1:7447"] == [local]  # the core has no TLS port
    assert [s["id"] for s in core["access_control"]["subjects"]] == ["host-nodes"]
    for broken in ({**config, "listen": {"endpoints": ["tcp/127.0.0.1:7447"]}},
                   {**config, "transport": {"link": {"tls": {"root_ca_certificate": "ca.pem"}}}}):
        with pytest.raises(ValueError, match="a fleet's cloud router"):
            split_config(broken)


def test_a_fleet_file_whose_revoked_is_not_a_list_is_refused(tmp_path: Path) -> None:
    fleet = tmp_path / "zenoh-fleet.json"
    fleet.write_text(json.dumps({"robots": {"r1": {"common_name": "r1.cn", "zid": "aa"}}, "revoked": "r1"}))
    with pytest.raises(ValueError, match="revoked is not a list"):
        read_fleet(fleet)
    fleet.write_text(json.dumps({"robots": {"r1": {"common_name": "r1.cn", "zid": "aa"}}, "revoked": ["r1"]}))
    assert read_fleet(fleet).admitted == {}


class _Session:
    """What the gate keeps of a front's Zenoh session here: only that it can be closed (no router is opened)."""

    def close(self) -> None:
        pass


def test_the_fronts_folder_is_private_and_kept_fresh_for_tmp_cleaners() -> None:
    """The robots' routers listen in a folder only the router's user may enter; systemd-tmpfiles deletes what
    in /tmp went unmodified for 10 days, so the router touches the folder and its sockets as it runs."""
    config = cloud_router(route(7448), listen_host="127.0.0.1", robots={}, local_port=7447,
                          tls=TlsFiles(ca="ca.pem", cert="server.pem", key="server.key"))
    router = FleetRouter(config, open_router=lambda _config: _Session())
    try:
        assert router.sockets.stat().st_mode & 0o777 == 0o700
        router.apply(FleetFile(robots={"r1": "r1.cn"}, zids={"r1": "aa"}, revoked=frozenset()))
        ((_, _, sock),) = router.fronts.values()
        sock.write_text("")  # where r1's router listens
        old = time.time() - 11 * 86400
        for path in (router.sockets, sock):
            os.utime(path, (old, old))
        router.refresh()
        assert [p for p in (router.sockets, sock) if time.time() - p.stat().st_mtime > 3600] == []
    finally:
        router.close()
    assert not router.sockets.exists()


def test_fronts_open_together_and_one_that_cannot_leaves_none_open_and_is_named(tmp_path: Path) -> None:
    """The fronts of the robots added are opened at once (real Zenoh routers, in this process); when one of them
    cannot open (here r2's: its socket's folder is gone), the error names r2, the fronts opened with it are
    closed and none of the three is admitted, so nothing half-open is left; given again, all three open."""
    pytest.importorskip("zenoh", reason="needs eclipse-zenoh (pip install 'fogiac[ros2]')")
    from fogiac.net.zenoh.errors import ZenohError
    from fogiac.net.zenoh.router import open_router

    (core,) = free_ports(1)
    config = cloud_router(route(7448), listen_host="127.0.0.1", robots={}, local_port=core,
                          tls=TlsFiles(ca="ca.pem", cert="server.pem", key="server.key"))
    sessions: dict[str, Any] = {}
    broken = {"r2"}

    def opening(front: dict[str, Any]) -> Any:
        (robot,) = {r["id"].split("-")[1] for r in front["access_control"]["rules"] if r["id"].startswith("robot-")}
        if robot in broken:
            front = {**front, "listen": {"endpoints": [f"unixsock-stream/{tmp_path}/gone/{robot}.sock"]}}
        sessions[robot] = session = open_router(front)
        return session

    router = FleetRouter(config, open_router=opening)
    three = FleetFile(robots={r: f"{r}.cn" for r in ("r1", "r2", "r3")}, zids={r: r for r in ("r1", "r2", "r3")},
                      revoked=frozenset())
    try:
        with pytest.raises(ZenohError, match=r"^robot r2's router behind the gate did not open \(zenoh router: .*"
                                             r"; the 2 opened with it closed$"):
            router.apply(three)
        assert set(sessions) == {"r1", "r3"} and all(s.is_closed() for s in sessions.values())
        assert router.fronts == {} and router.admitted == {} and list(router.sockets.iterdir()) == []
        broken.clear()
        assert router.apply(three) == ["robot r1: admitted", "robot r2: admitted", "robot r3: admitted"]
        assert set(router.admitted.values()) == {"r1", "r2", "r3"} and not any(s.is_closed() for s in sessions.values())
        assert all(sock.is_socket() for _, _, sock in router.fronts.values())
    finally:
        router.close()
    assert all(s.is_closed() for s in sessions.values())
