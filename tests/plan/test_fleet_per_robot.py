"""``serve: per_robot`` in the plan and what it renders, purely: one service per robot with the ROS arguments
that put it in the robot's namespace, each robot's edge end carrying its own instance's topics and no other's,
the cloud end's command and a robot's access naming no per-robot topic bare, and each robot bearing its own
instance's share of the host (a host's processes share its hour, a per-robot node counting one per instance).
A robot added to such a fleet shows in the plan diff with its instance, and no node changes."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.manifest.schema import parse_manifest
from fogiac.net.relay.deploy import fleet_access
from fogiac.net.relay.services import relay_service
from fogiac.plan import fleet
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Plan
from fogiac.provision import services as svc
from tests.plan.test_fleet_diff import _deploy

runner = CliRunner()
ROBOTS = """robots:
  - {name: arm1, ros_master: "http://127.0.0.1:11312"}
  - {name: arm2, ros_master: "http://127.0.0.1:11313"}
"""
ARM3 = '  - {name: arm3, ros_master: "http://127.0.0.1:11314"}\n'
NODES = """nodes:
  - name: slam
    machine: t3.micro
    command: [slam_node, --rate, "10"]
    topics: {in: [/scan], out: [/map]}
    serve: per_robot
  - name: planner
    machine: t3.micro
    command: [sleep, "3600"]
    topics: {in: [/plan/request], out: [/plan/path]}
    host: lab
  - name: mapper
    machine: t3.micro
    command: [sleep, "3600"]
    topics: {in: [/scan], out: [/merged]}
    serve: per_robot
    host: lab
"""


def _plan(robots: str = ROBOTS, cloud: str = "cloud: {provider: aws, region: us-west-2}\n") -> Plan:
    return compile_plan(parse_manifest("name: lab\n" + cloud + robots + NODES.split("  - name: planner")[0],
                                       base=Path.cwd()))


def _where() -> svc.Where:
    base = "/home/ubuntu/.fogiac/lab-dev/slam"
    return svc.Where(layout=svc.Layout(base), runtime=svc.NATIVE, master_port=11311, relay_port=11411,
                     ros_address="127.0.0.1", python="python3", code_root=f"{base}/lib", user="ubuntu")


def test_one_service_per_robot_each_in_its_namespace() -> None:
    plan = _plan()
    services = svc.node_services(plan, plan.host("slam"), _where())
    assert [s.name for s in services] == ["node-slam@arm1", "node-slam@arm2"]
    assert "slam_node --rate 10 __ns:=/arm1 /map:=/arm1/map /scan:=/arm1/scan\n" in services[0].script
    assert "slam_node --rate 10 __ns:=/arm2 /map:=/arm2/map /scan:=/arm2/scan\n" in services[1].script
    assert "node-slam@arm2" in services[1].unit


def test_each_robots_link_carries_its_own_instances_topics_and_the_cloud_end_none_bare() -> None:
    plan = _plan()
    (route,) = plan.routes
    assert (route.to_cloud, route.to_edge) == (("/scan",), ("/map",))  # the plan shows what the node lists
    arm1 = fleet.robot_route(plan, route, "arm1")
    assert (arm1.to_cloud, arm1.to_edge) == (("/arm1/scan",), ("/arm1/map",))
    assert "--out /scan" not in relay_service(plan, plan.host("slam"), _where()).script
    assert "--topics ''" in relay_service(plan, plan.host("slam"), _where()).script  # nothing crosses for no robot
    rules = fleet_access(plan, plan.host("slam")).to_json()
    assert rules["per_robot"] == [{"node": "slam", "in": ["/scan"], "out": ["/map"]}]
    robots = rules["robots"]
    assert isinstance(robots, dict) and [r["topics"] for r in robots.values()] == [[], []]
    assert "shared" not in rules


def _one_machine() -> Plan:
    """A shared planner and a per-robot mapper (reading /scan) put on one priced machine, as the hosts target
    places nodes (``host:``), with the aws target's price for it."""
    plan = compile_plan(parse_manifest("name: lab\ncloud: {provider: aws, region: us-west-2}\n" + ROBOTS
                                       + "nodes:\n  - name: planner"
                                       + NODES.split("  - name: planner")[1].replace("    host: lab\n", ""),
                                       base=Path.cwd()))
    (first, _) = plan.hosts
    host = dataclasses.replace(first, name="lab", nodes=("planner", "mapper"))
    nodes = tuple(dataclasses.replace(node, host="lab") for node in plan.nodes)
    (route, _) = plan.routes
    route = dataclasses.replace(route, host="lab", to_cloud=("/plan/request", "/scan"),
                                to_edge=("/merged", "/plan/path"))
    return dataclasses.replace(plan, hosts=(host,), nodes=nodes, routes=(route,))


def test_a_shared_node_beside_a_per_robot_one_keeps_its_topics() -> None:
    plan = _one_machine()
    (route,) = plan.routes
    arm2 = fleet.robot_route(plan, route, "arm2")
    assert arm2.to_cloud == ("/arm2/scan", "/plan/request") and arm2.to_edge == ("/arm2/merged", "/plan/path")
    rules = fleet_access(plan, plan.host("lab"))
    assert [(p.node, sorted(p.requests)) for p in rules.shared] == [("planner", ["/plan/request"])]
    assert [n.node for n in rules.per_robot] == ["mapper"]
    assert {r.name: sorted(r.topics) for r in rules.robots.values()} == {
        "arm1": ["/plan/path", "/plan/request"], "arm2": ["/plan/path", "/plan/request"]}


def test_each_robot_bears_its_own_instance_and_the_shares_add_up_to_the_host() -> None:
    """Three processes on one machine (the planner, two robots' mappers): a third of its hour each."""
    plan = _one_machine()
    hourly = plan.host("lab").usd_per_hour
    assert hourly == pytest.approx(0.0104)
    assert fleet.node_usd_per_hour(plan, plan.node("mapper")) == pytest.approx(hourly * 2 / 3)
    assert fleet.share(plan, plan.node("mapper")) == pytest.approx(hourly / 3, abs=1e-6)
    assert fleet.share(plan, plan.node("planner")) == pytest.approx(hourly / 6, abs=1e-6)
    robots = {r["name"]: r for r in fleet.robots(plan) or []}
    vpn = sum(line.total for line in plan.cost if line.per_robot)  # one Client VPN connection per robot
    assert vpn == pytest.approx(2 * 0.05)
    assert sum(r["usd_per_hour"] for r in robots.values()) == pytest.approx(hourly + vpn, abs=1e-5)
    assert robots["arm1"]["instances"] == ["mapper@arm1 on lab"]


def test_a_robot_added_shows_its_instance_and_no_node_changed(tmp_path: Path) -> None:
    text = "name: lab\ncloud: {provider: local}\n" + ROBOTS + NODES.split("  - name: planner")[0]
    manifest = _deploy(tmp_path, text)
    manifest.write_text(text.replace(ROBOTS, ROBOTS + ARM3))
    shown = runner.invoke(app, ["plan", str(manifest), "--detailed-exitcode"])
    assert shown.exit_code == 2, shown.output
    lines = [line.strip() for line in shown.output.splitlines()]
    assert ("! robots +arm3: certificates, access rules, edge processes and per-robot instances only; no host is "
            "replaced or restarted (0 hosts to replace)") in lines
    assert "per-robot instances: slam@arm3 on slam (started; the host's other processes untouched)" in lines
    assert "Plan: 0 to add, 0 to change, 0 to destroy. Robots: 1 to add, 0 to change, 0 to remove." in lines


def test_a_per_robot_instance_in_a_container_is_named_without_an_at() -> None:
    """Engines take no ``@`` in a container's name: arm1's instance runs as ``fogiac-lab-dev-slam.arm1``."""
    plan = _plan()
    where = svc.Where(layout=svc.Layout("/home/ubuntu/.fogiac/lab-dev/slam"), runtime=svc.CONTAINER,
                      master_port=11311, relay_port=11411, ros_address="127.0.0.1", python="python3",
                      code_root="/home/ubuntu/.fogiac/lab-dev/slam/lib", user="ubuntu")
    first, _ = svc.node_services(plan, plan.host("slam"), where)
    assert first.name == "node-slam@arm1"
    assert "--name fogiac-lab-dev-slam.arm1 " in first.script and "@" not in first.script.split("--name ")[1].split()[0]
    assert "slam_node --rate 10 __ns:=/arm1 /map:=/arm1/map /scan:=/arm1/scan" in first.script
