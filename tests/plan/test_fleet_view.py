"""What ``fogiac plan`` shows of a fleet (``robots:``): each robot with its ROS master, certificate, access and
share of the hour; each node with whom it serves, its instances and each robot's share of its cost. In the
terminal table, the JSON document (``--json``, a saved plan) and the pull-request comment (``--markdown``);
a one-robot manifest's plan shows none of it."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.certs import edge_identity
from fogiac.cli import app
from fogiac.manifest.schema import parse_manifest
from fogiac.net.relay import deploy as relay_deploy
from fogiac.plan import fleet
from fogiac.plan.compile import compile_plan
from fogiac.plan.document import document
from fogiac.plan.model import Plan
from tests.plan.test_fleet import FLEET

runner = CliRunner()
ONE = FLEET.split("robots:")[0] + 'edge: {ros_master: "http://127.0.0.1:11312"}\nnodes:' \
    + FLEET.split("nodes:")[1].replace("    serve: [arm1, arm3]\n", "")
# Priced hosts (t3.micro, $0.0104/h each): a local sandbox costs nothing.
PRICED = FLEET.replace("cloud: {provider: local}", "cloud: {provider: aws, region: us-west-2}")


def _plan(text: str = PRICED, target: str = "aws") -> Plan:
    return compile_plan(parse_manifest(text, base=Path.cwd()), target=target)


def test_each_robot_bears_its_share_and_the_shares_add_up_to_the_hosts() -> None:
    plan = _plan()
    hourly = {h.name: h.usd_per_hour for h in plan.hosts}
    assert hourly["planner"] == pytest.approx(0.0104) and hourly["grasp"] == pytest.approx(0.0104)
    robots = {r["name"]: r for r in fleet.robots(plan) or []}
    # planner: every robot, a third each; grasp: arm1 and arm3, half each; each its own Client VPN connection
    assert robots["arm2"]["usd_per_hour"] == pytest.approx(0.0104 / 3 + 0.05, abs=1e-6)
    assert robots["arm1"]["usd_per_hour"] == pytest.approx(0.0104 / 3 + 0.0104 / 2 + 0.05, abs=1e-6)
    assert sum(r["usd_per_hour"] for r in robots.values()) == pytest.approx(0.0208 + 3 * 0.05, abs=1e-5)
    assert robots["arm2"]["certificate"] == "arm2.edge.lab-dev.fogiac"
    assert robots["arm2"]["access"] == ["/arm2/...", "/plan/path", "/plan/request"]  # not grasp's topics
    assert robots["arm3"]["access"] == ["/arm3/...", "/grasp/reply", "/grasp/request", "/plan/path", "/plan/request"]
    assert robots["arm1"]["edge_links"] == ["planner", "grasp"] and robots["arm2"]["nodes"] == ["planner"]


def test_on_aws_over_the_vpn_each_robot_also_bears_its_own_client_vpn_connection() -> None:
    """On aws (the Client VPN unless the manifest says otherwise) each robot's edge is a connection AWS bills by
    the hour: the robot's cost was only its nodes' shares, so three robots' rows left out three connection-hours the plan's total counted. Now each
    robot's row carries one, and the robots' costs add up to the hosts' and the connections; the subnet
    association, which no single robot brings, stays the stack's. A one-robot plan's document is unchanged."""
    plan = _plan()
    (connections,) = [line for line in plan.cost if line.per_robot]
    assert connections.quantity == 3 and connections.usd_per_hour == pytest.approx(0.05)
    robots = {r["name"]: r for r in fleet.robots(plan) or []}
    assert robots["arm2"]["usd_per_hour"] == pytest.approx(0.0104 / 3 + 0.05, abs=1e-6)
    assert sum(r["usd_per_hour"] for r in robots.values()) == pytest.approx(0.0208 + 3 * 0.05, abs=1e-5)
    assert [line["per_robot"] for line in plan.to_dict()["cost"] if "per_robot" in line] == [True]
    one = _plan(ONE.replace("cloud: {provider: local}", "cloud: {provider: aws, region: us-west-2}"))
    assert not any(line.per_robot for line in one.cost)
    assert all("per_robot" not in line for line in one.to_dict()["cost"])


def test_a_topic_in_another_robots_namespace_is_not_shown_in_a_robots_access() -> None:
    """A shared node's listed topic in arm2's namespace (``/arm2/status``) is arm2's alone at every cloud end
    (:func:`fogiac.net.relay.deploy.fleet_access`); the plan listed it as arm1's and arm3's to cross too, so a
    reviewer read a neighbour's topic as open to them. The plan's access is what the access files say."""
    plan = _plan(PRICED.replace("out: [/plan/path]", "out: [/plan/path, /arm2/status]"))
    shown = {r["name"]: r["access"] for r in fleet.robots(plan) or []}
    assert shown["arm1"] == ["/arm1/...", "/grasp/reply", "/grasp/request", "/plan/path", "/plan/request"]
    assert shown["arm2"] == ["/arm2/...", "/arm2/status", "/plan/path", "/plan/request"]
    for edge in plan.edges:
        enforced = set().union(*(relay_deploy.fleet_access(plan, spec).robots[
            edge_identity(plan.stack, edge.named)].topics for spec in plan.hosts))
        assert set(shown[edge.name][1:]) == enforced, edge.name


def test_a_per_robot_node_runs_one_instance_per_robot_and_splits_its_host() -> None:
    plan = _plan()
    planner = dataclasses.replace(plan.node("planner"), per_robot=True)
    plan = dataclasses.replace(plan, nodes=(planner, plan.node("grasp")))
    doc = document(plan, [], manifest_path="m.yaml", manifest_sha256="0" * 64)
    row = next(n for n in doc["nodes"] if n["name"] == "planner")
    assert (row["serve"], row["instances"], row["serves"]) == ("per_robot", 3, ["arm1", "arm2", "arm3"])
    assert row["usd_per_hour_per_robot"] == pytest.approx(0.0104 / 3, abs=1e-6)
    # its topics live in each robot's namespace: nothing shared added to a robot's access
    assert next(r for r in doc["robots"] if r["name"] == "arm2")["access"] == ["/arm2/..."]


def test_an_unknown_price_is_an_unknown_share_never_zero() -> None:
    plan = _plan()
    hosts = tuple(dataclasses.replace(h, usd_per_hour=None) if h.name == "grasp" else h
                  for h in plan.hosts)
    plan = dataclasses.replace(plan, hosts=hosts)
    robots = {r["name"]: r for r in fleet.robots(plan) or []}
    assert robots["arm1"]["usd_per_hour"] is None and robots["arm2"]["usd_per_hour"] is not None
    assert fleet.node_row(plan, plan.node("grasp"))["usd_per_hour_per_robot"] is None


def test_plan_shows_the_robots_and_whom_each_node_serves(tmp_path: Path) -> None:
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(FLEET)
    shown = runner.invoke(app, ["plan", str(manifest)], env={"COLUMNS": "250"})
    assert shown.exit_code == 0, shown.output
    out = shown.output
    assert "robots (3; each its own certificate, namespace and access)" in out
    arm2 = next(line for line in out.splitlines() if line.startswith("│ arm2 "))
    assert "http://127.0.0.1:11313" in arm2 and "arm2.edge.lab-dev.fogiac" in arm2
    assert "/arm2/..., /plan/path, /plan/request" in arm2 and "grasp" not in arm2
    planner = next(line for line in out.splitlines() if line.startswith("│ planner ") and "sleep" in line)
    grasp = next(line for line in out.splitlines() if line.startswith("│ grasp ") and "sleep" in line)
    assert "all (3)" in planner and "1 (shared)" in planner
    assert "arm1, arm3" in grasp

    doc = json.loads(runner.invoke(app, ["plan", str(manifest), "--json"]).output)
    assert [r["name"] for r in doc["robots"]] == ["arm1", "arm2", "arm3"]
    assert {n["name"]: (n["serves"], n["instances"]) for n in doc["nodes"]} == {
        "planner": (["arm1", "arm2", "arm3"], 1), "grasp": (["arm1", "arm3"], 1)}
    saved = tmp_path / "plan.json"
    assert runner.invoke(app, ["plan", str(manifest), "--out", str(saved)]).exit_code == 0
    assert json.loads(saved.read_text())["robots"] == doc["robots"]

    comment = runner.invoke(app, ["plan", str(manifest), "--markdown"]).output
    assert "+ grasp on grasp (command: sleep 3600), serves 2 robots (arm1, arm3), 1 instance (shared)" in comment


def test_a_one_robot_plan_shows_no_fleet(tmp_path: Path) -> None:
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(ONE)
    out = runner.invoke(app, ["plan", str(manifest)], env={"COLUMNS": "250"}).output
    assert "robots (" not in out and "serves" not in out and "instances" not in out
    doc = json.loads(runner.invoke(app, ["plan", str(manifest), "--json"]).output)
    assert "robots" not in doc and all("serves" not in n and "instances" not in n for n in doc["nodes"])
    assert "serves" not in runner.invoke(app, ["plan", str(manifest), "--markdown"]).output
