"""Issue 34, ROS 2: ``serve: per_robot`` over Zenoh, as pure functions: what ``up`` renders and what the rules let
through.

One service per robot whose command carries ROS 2's ``--ros-args -r __ns:=/<robot>`` and the listed topics
remapped into the namespace; no fleet process and no shared pair for the node (its instances' topics are
already each robot's own); the fleet's routers let each robot's session reach its own instance's keys and no
other's (zenoh's own key-expression matching, on the rules the routers load); each robot's edge side carries
its own instance's topics; the plan names each robot's instance and its cost. The running parts:
``tests/fleet/test_fleet_zenoh_local.py``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from fogiac.errors import ManifestError
from fogiac.manifest.schema import parse_manifest
from fogiac.net import middleware
from fogiac.net.zenoh import deploy, tls
from fogiac.net.zenoh.config import fleet_access_control, topic_key
from fogiac.net.zenoh.middleware import instance_args
from fogiac.plan import fleet
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Plan
from fogiac.provision import services as svc
from tests.net.zenoh.slamnode import ros_args
from tests.plugins.beacon import ENTRY_POINTS as BEACON_ENTRY_POINTS
from tests.plugins.install import installed

zenoh = pytest.importorskip("zenoh", reason="needs eclipse-zenoh (pip install 'fogiac[ros2]')")

ROBOTS = """robots:
  - {name: r1, zenoh_router: "tcp/127.0.0.1:7451"}
  - {name: r2, zenoh_router: "tcp/127.0.0.1:7452"}
"""
R3 = '  - {name: r3, zenoh_router: "tcp/127.0.0.1:7453"}\n'
NODES = """nodes:
  - name: slam
    machine: t3.micro
    command: [ros2, run, slam_pkg, slam_node, --ros-args, -p, "rate:=10"]
    topics: {in: [/scan], out: [/map]}
    serve: per_robot
  - name: planner
    machine: t3.micro
    command: [sleep, "3600"]
    topics: {in: [/plan_request], out: [/plan_result]}
"""
KEY = "std_msgs::msg::dds_::Header_/RIHS01_x"  # a data key's type and hash chunks


def _plan(robots: str = ROBOTS, cloud: str = "cloud: {provider: local, runtime: native}\n") -> Plan:
    return compile_plan(parse_manifest("name: lab\nros: {distro: jazzy}\n" + cloud + robots + NODES,
                                       base=Path.cwd()), target="local")


def _where(tmp_path: Path) -> svc.Where:
    return svc.Where(layout=svc.Layout(str(tmp_path / "slam")), runtime=svc.NATIVE, master_port=17447,
                     relay_port=7448, ros_address="127.0.0.1", python="python3", code_root=str(Path.cwd()))


def test_ros2_arguments_put_an_instance_in_its_robots_namespace() -> None:
    args = instance_args("r1", ("/scan", "/map", "/scan"))
    assert args == ("--ros-args", "-r", "__ns:=/r1", "-r", "/map:=/r1/map", "-r", "/scan:=/r1/scan")
    # the stand-in node reads them as rcl does, after a --ros-args block of the command's own
    assert ros_args(["--ros-args", "-p", "rate:=10", *args]) == ("/r1", {"/map": "/r1/map", "/scan": "/r1/scan"})


def test_one_service_per_robot_each_with_its_ros_args(tmp_path: Path) -> None:
    plan = _plan()
    services = svc.node_services(plan, plan.host("slam"), _where(tmp_path))
    assert [s.name for s in services] == ["node-slam@r1", "node-slam@r2"]
    for robot, service in zip(("r1", "r2"), services, strict=True):
        assert (f"slam_node --ros-args -p rate:=10 --ros-args -r __ns:=/{robot} -r /map:=/{robot}/map "
                f"-r /scan:=/{robot}/scan\n") in service.script
        assert f"node-slam@{robot}" in service.unit and "zenoh-router" in service.unit  # after the host's router


def test_a_per_robot_node_gets_no_fleet_process_and_no_shared_pair(tmp_path: Path) -> None:
    """Its instances' topics are each robot's own: a mux carrying every robot's /<robot>/scan to a bare /scan
    would hand every robot's scans to a node no instance listens on."""
    plan = _plan()
    spec = plan.host("slam")
    assert deploy.shared_pairs(plan, spec) == []
    assert deploy.link_services(plan, spec, _where(tmp_path)) == ()
    ((_, body, _),) = deploy.fleet_files(plan, spec, revoked=())
    assert b'"shared": []' in body
    assert [p[0] for p in deploy.shared_pairs(plan, plan.host("planner"))] == ["planner"]


def test_each_robots_rules_reach_its_own_instance_only() -> None:
    """The routers' rules for r1 (the cloud's for r1's certificate) match r1's instance's keys, both ways, and
    none of r2's instance's nor the bare topic's; revoked, r1 has no rule at all."""
    acl = fleet_access_control({"r1": "r1.cn", "r2": "r2.cn"})
    keys = {robot: [k for rule in acl["rules"] if rule["id"].startswith(f"robot-{robot}-data")
                    for k in rule["key_exprs"]] for robot in ("r1", "r2")}

    def reaches(robot: str, topic: str) -> bool:
        key = zenoh.KeyExpr(topic_key(topic).replace("*/", "0/", 1).replace("/*/*", f"/{KEY}"))
        return any(zenoh.KeyExpr(k).intersects(key) for k in keys[robot])

    for robot, other in (("r1", "r2"), ("r2", "r1")):
        mine = [fleet.in_namespace(robot, t) for t in ("/scan", "/map")]
        theirs = [fleet.in_namespace(other, t) for t in ("/scan", "/map")]
        assert all(reaches(robot, t) for t in mine)
        assert not [t for t in (*theirs, "/scan", "/map") if reaches(robot, t)]
    revoked = fleet_access_control({"r1": "r1.cn", "r2": "r2.cn"}, revoked=("r1",))
    assert not [r for r in revoked["rules"] if r["id"].startswith("robot-r1")]


def test_each_robots_edge_carries_its_own_instances_topics() -> None:
    plan = _plan()
    for robot in ("r1", "r2"):
        (edge,) = [e for e in plan.edges if e.name == robot]
        assert [deploy.robot_topic(plan, edge, t) for t in ("/scan", "/map")] == [f"/{robot}/scan", f"/{robot}/map"]


def test_the_plan_shows_each_robots_instance_and_cost() -> None:
    """On aws prices, two processes share the slam host (r1's and r2's instances): half its hour each."""
    plan = compile_plan(parse_manifest("name: lab\nros: {distro: jazzy}\ncloud: {provider: aws, region: us-west-2}\n"
                                       + ROBOTS + NODES, base=Path.cwd()))
    rows = {r["name"]: r for r in fleet.robots(plan) or []}
    assert rows["r1"]["instances"] == ["slam@r1 on slam"] and rows["r2"]["instances"] == ["slam@r2 on slam"]
    assert rows["r1"]["certificate"] == tls.edge_name(plan.stack, "r1")
    slam = plan.host("slam").usd_per_hour
    assert slam is not None and fleet.share(plan, plan.node("slam")) == pytest.approx(slam / 2, abs=1e-6)
    assert fleet.node_row(plan, plan.node("slam"))["instances"] == 2


def test_a_robot_added_starts_its_instance_and_changes_no_other_service(tmp_path: Path) -> None:
    plan, three = _plan(), _plan(ROBOTS + R3)
    where = _where(tmp_path)
    two = {s.name: s.script for s in svc.node_services(plan, plan.host("slam"), where)}
    more = {s.name: s.script for s in svc.node_services(three, three.host("slam"), where)}
    assert set(more) - set(two) == {"node-slam@r3"} and {k: more[k] for k in two} == two
    host = [(s.name, s.script) for s in deploy.host_services(plan, plan.host("slam"), where, certs=tmp_path / "c")]
    again = [(s.name, s.script) for s in deploy.host_services(three, three.host("slam"), where, certs=tmp_path / "c")]
    assert host == again  # the router follows the fleet file: a robot added restarts no router


def test_a_middleware_without_instance_arguments_is_refused_in_one_line(tmp_path: Path) -> None:
    """A middleware plug-in whose ROS generation puts no node in a namespace (no ``instance_args``) keeps
    ``serve: per_robot`` refused at validate, naming it: the test-only beacon (``tests/plugins/beacon/``),
    installed through its entry point as a plug-in would be, whose Launching gives none."""
    manifest = ("name: lab\nros: {distro: lighthouse}\ncloud: {provider: local, runtime: native}\n"
                "robots:\n  - {name: r1}\n" + NODES)
    try:
        with installed(tmp_path / "site", "fogiac_beacon", BEACON_ENTRY_POINTS):
            assert middleware.get("beacon").launching.instance_args is None
            refusal = (r"nodes\[0\]\.serve: serve: per_robot \(one instance per robot\) needs a middleware that puts "
                       r"a node in a robot's namespace; ROS lighthouse crosses through beacon, which has no per-robot "
                       r"instances yet: give all or a list of robots")
            with pytest.raises(ManifestError, match=refusal) as refused:
                parse_manifest(manifest, base=Path.cwd())
            assert len(str(refused.value).splitlines()) == 1, refused.value
    finally:
        middleware.unregister("beacon")  # the loaded halves are cached per process
