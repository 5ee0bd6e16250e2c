"""A robot added to or removed from a deployed fleet is, in ``fogiac plan``'s diff, its certificate, its access
rules and its edge process, and nothing else: no host, instance, disk or security group is replaced.

The deployed side is a real stack record, written through :class:`fogiac.state.StackState` as ``up`` writes it
(the applied plan document, the deployment, the edges list); the manifest on disk then lists one robot more,
or one fewer, and the real CLI compares them.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac import deployment, targets
from fogiac.cli import app
from fogiac.lifecycle.edge import record_edge
from fogiac.manifest.revision import load_revision
from fogiac.plan.compile import compile_plan
from fogiac.plan.diff import diff_documents
from fogiac.plan.document import plan_document
from fogiac.plan.review import terminal
from fogiac.state import StackState
from tests.docs.blocks import REPO, blocks, normalise
from tests.plan.test_fleet import FLEET

runner = CliRunner()
ARM3 = '  - {name: arm3, ros_master: "http://127.0.0.1:11314"}\n'
TWO = FLEET.replace(ARM3, "").replace("serve: [arm1, arm3]", "serve: [arm1]")
THREE = FLEET.replace("serve: [arm1, arm3]", "serve: [arm1]")
AWS = ("cloud: {provider: local}", "cloud: {provider: aws, region: us-west-2}")


def _deploy(folder: Path, text: str) -> Path:
    """A stack record as a complete ``up`` of ``text`` leaves it: applied document, deployment, edges."""
    manifest = folder / "fogiac.yaml"
    manifest.write_text(text)
    plan = compile_plan(load_revision(str(manifest)).manifest)
    doc = plan_document(plan, targets.get(plan.target).declare(plan), manifest=manifest)
    deployment.begin(plan, manifest)
    deployment.finish(plan, manifest, plan_digest=doc["plan_digest"], applied=doc)
    record_edge(plan, {"target": plan.target, "edge_master": plan.edge_master,
                       "relays": {route.host: f"127.0.0.1:{route.port}" for route in plan.routes},
                       "started_edge_master": False, "nodes": {n.name: n.host for n in plan.nodes}})
    assert [e["name"] for e in StackState(plan.stack).get(StackState.EDGES)] == [e.name for e in plan.edges]
    return manifest


@pytest.mark.parametrize("cloud", ["local", "aws"])
def test_a_robot_added_is_its_certificate_access_and_edge_process_only(tmp_path: Path, cloud: str) -> None:
    change = AWS if cloud == "aws" else ("", "")
    manifest = _deploy(tmp_path, TWO.replace(*change))
    manifest.write_text(THREE.replace(*change))  # the pull request: arm3 joins the fleet

    shown = runner.invoke(app, ["plan", str(manifest), "--detailed-exitcode"])
    assert shown.exit_code == 2, shown.output
    lines = [line.strip() for line in shown.output.splitlines()]
    assert "robots (certificate, access rules, edge process):" in lines
    assert "+ robot arm3 (ROS master http://127.0.0.1:11314)" in lines
    assert "certificate arm3.edge.lab-dev.fogiac (issued by the stack's CA)" in lines
    assert "access rules: may cross /arm3/..., /plan/path, /plan/request" in lines
    assert "edge process on this machine: linked to planner, grasp (started)" in lines
    assert ("! robots +arm3: certificates, access rules and edge processes only; no host is replaced or restarted "
            "(0 hosts to replace)") in lines
    assert "Plan: 0 to add, 0 to change, 0 to destroy. Robots: 1 to add, 0 to change, 0 to remove." in lines
    assert "hosts:" not in lines and "nodes:" not in lines and "resources:" not in lines
    assert not any(line.startswith("~ robot arm") for line in lines)  # the others keep their access
    if cloud == "local":  # the fleet guide shows this very output
        shown_in_guide = [b for b in blocks(REPO / "docs" / "guides" / "fleet.md") if b.kind == "checked"
                          and b.field("test") == "tests/plan/test_fleet_diff.py"]
        assert [normalise(b.body) for b in shown_in_guide] == [normalise(shown.output.strip("\n") + "\n")]

    doc = json.loads(runner.invoke(app, ["plan", str(manifest), "--json"]).output)
    changes = doc["changes"]
    assert [r["name"] for r in changes["robots"]["added"]] == ["arm3"] and not changes["robots"]["removed"]
    assert (changes["add"], changes["change"], changes["destroy"]) == (0, 0, 0)
    assert changes["hosts"] == {"added": [], "removed": [], "changed": []}
    assert {r["action"] for r in doc["resources"]} <= {"no-op"}  # no instance, disk or security group touched

    comment = runner.invoke(app, ["plan", str(manifest), "--markdown"]).output
    assert "#### robots (certificate, access rules, edge process)" in comment
    assert "+ robot arm3 (ROS master http://127.0.0.1:11314)" in comment and "replaced, not updated" not in comment


def test_a_robot_removed_and_a_serve_list_extended(tmp_path: Path) -> None:
    """arm3 leaves; arm2 joins grasp's list: arm2's access rules grow, grasp itself is not changed."""
    manifest = _deploy(tmp_path, FLEET)
    manifest.write_text(TWO.replace("serve: [arm1]", "serve: [arm1, arm2]"))
    lines = [line.strip() for line in runner.invoke(app, ["plan", str(manifest)]).output.splitlines()]
    assert "- robot arm3 (ROS master http://127.0.0.1:11314)" in lines
    assert "certificate arm3.edge.lab-dev.fogiac (no longer accepted by any cloud end)" in lines
    assert "edge process on this machine: linked to planner, grasp (stopped)" in lines
    assert "~ robot arm2" in lines
    assert ("access: [/arm2/..., /plan/path, /plan/request] -> "
            "[/arm2/..., /grasp/reply, /grasp/request, /plan/path, /plan/request]") in lines
    assert "Plan: 0 to add, 0 to change, 0 to destroy. Robots: 0 to add, 1 to change, 1 to remove." in lines
    assert "nodes:" not in lines and "hosts:" not in lines


def test_a_one_robot_diff_says_nothing_of_robots(tmp_path: Path) -> None:
    one = FLEET.split("robots:")[0] + 'edge: {ros_master: "http://127.0.0.1:11312"}\nnodes:' \
        + FLEET.split("nodes:")[1].replace("    serve: [arm1, arm3]\n", "")
    manifest = _deploy(tmp_path, one)
    manifest.write_text(one.replace("127.0.0.1:11312", "127.0.0.1:11399"))
    shown = runner.invoke(app, ["plan", str(manifest), "--json"]).output
    assert "robots" not in json.loads(shown)["changes"]
    doc = json.loads(shown)
    diff = diff_documents(deployment.read_applied(doc["stack"]), doc)
    assert diff.robots.empty and not diff.fleet
    assert not any("robot" in line for line in terminal(diff, against="applied"))


def test_a_fleet_applied_before_robots_were_shown_compares_by_its_edges(tmp_path: Path) -> None:
    """An applied fleet document without ``robots`` (a fogiac before this one) lists its edges: the robots
    compare by name and entry, so only the new one shows, and the others no made-up change."""
    manifest = _deploy(tmp_path, TWO)
    stack = "lab-dev"

    def older(document: dict[str, object]) -> None:
        applied = document[StackState.APPLIED]
        assert isinstance(applied, dict)
        del applied["robots"]
        for node in applied["nodes"]:
            for key in ("serves", "serve", "instances", "usd_per_hour_per_robot"):
                node.pop(key)

    StackState(stack).update(older)
    manifest.write_text(THREE)
    doc = json.loads(runner.invoke(app, ["plan", str(manifest), "--json"]).output)
    robots = doc["changes"]["robots"]
    assert [r["name"] for r in robots["added"]] == ["arm3"] and robots["changed"] == [] and robots["removed"] == []
    assert doc["changes"]["nodes"] == {"added": [], "removed": [], "changed": []}
