"""A fleet in the manifest (``robots:``): each robot one edge of the plan, with its name and master; ``edge:``
stays the one-robot shorthand; a node's ``serve:`` list is the plan's, and every robot is served otherwise."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.errors import ManifestError
from fogiac.manifest.schema import parse_manifest
from fogiac.net import middleware
from fogiac.net.relay import deploy as relay_deploy
from fogiac.net.relay.middleware import RELAY
from fogiac.plan.compile import compile_plan
from fogiac.plan.document import document
from fogiac.plan.model import EdgeSpec

FLEET = """name: lab
cloud: {provider: local}
robots:
  - {name: arm1, ros_master: "http://127.0.0.1:11312"}
  - {name: arm2, ros_master: "http://127.0.0.1:11313", compression: zstd}
  - {name: arm3, ros_master: "http://127.0.0.1:11314"}
nodes:
  - name: planner
    machine: t3.micro
    command: [sleep, "3600"]
    topics: {in: [/plan/request], out: [/plan/path]}
  - name: grasp
    machine: t3.micro
    command: [sleep, "3600"]
    topics: {in: [/grasp/request], out: [/grasp/reply]}
    serve: [arm1, arm3]
"""


def test_each_robot_is_an_edge_of_its_own_with_its_master() -> None:
    plan = compile_plan(parse_manifest(FLEET, base=Path.cwd()), target="local")
    assert plan.edges == (EdgeSpec("arm1", "http://127.0.0.1:11312"),
                          EdgeSpec("arm2", "http://127.0.0.1:11313", compression="zstd"),
                          EdgeSpec("arm3", "http://127.0.0.1:11314"))
    assert plan.fleet and all(edge.named == edge.name for edge in plan.edges)  # each its own certificate's name
    assert plan.robots_of(plan.node("planner")) == ("arm1", "arm2", "arm3")
    assert plan.robots_of(plan.node("grasp")) == ("arm1", "arm3")
    out = plan.to_dict()
    assert [e.get("compression") for e in out["edges"]] == [None, "zstd", None]
    assert "serves" not in out["nodes"][0] and out["nodes"][1]["serves"] == ("arm1", "arm3")
    doc = document(plan, [], manifest_path="m.yaml", manifest_sha256="0" * 64)
    assert [e["name"] for e in doc["edges"]] == ["arm1", "arm2", "arm3"]


def test_the_edge_block_stays_the_one_robot_shorthand() -> None:
    one = FLEET.split("robots:")[0] + 'edge: {ros_master: "http://127.0.0.1:11312"}\nnodes:' + FLEET.split("nodes:")[1]
    plan = compile_plan(parse_manifest(one.replace("    serve: [arm1, arm3]\n", ""), base=Path.cwd()),
                        target="local")
    (edge,) = plan.edges
    assert edge.shorthand and not plan.fleet and edge.name == plan.stack
    assert "edges" not in plan.to_dict() and "serves" not in plan.to_dict()["nodes"][1]


@pytest.mark.parametrize(("change", "expect"), [
    (("ros_master: \"http://127.0.0.1:11313\", compression: zstd", "ros_master: \"http://127.0.0.1:11313\", "
      "compression: bzip9"), "robots[1].compression"),
    (("name: planner\n", "name: planner\n    serve: [arm4]\n"), "nodes[0].serve: 'arm4' is not in robots"),
    (("serve: [arm1, arm3]", "serve: []"), "nodes[1].serve: serves no robot"),
    (("cloud: {provider: local}", "cloud: {provider: local}\nros: {distro: humble}"),
     "robots[1].zenoh_router: 'tcp/127.0.0.1:7447' is another robot's edge router too"),  # ROS 2: one router each
])
def test_a_bad_fleet_is_named_in_one_line(change: tuple[str, str], expect: str) -> None:
    text = FLEET.replace(*change)
    assert text != FLEET
    with pytest.raises(ManifestError) as err:
        parse_manifest(text, source="fogiac.yaml", base=Path.cwd())
    assert any(expect in line for line in err.value.problems), err.value.problems


def test_up_refuses_a_fleet_its_middleware_cannot_deploy_in_one_line_and_creates_nothing(
        tmp_path: Path, _state_dir: Path) -> None:
    """A middleware deployment that does not say ``deploys_fleet`` (a plug-in written before fleets) would link
    every robot to every topic: up refuses the fleet before anything exists (plan and validate work)."""

    class BeforeFleets:  # the relay's deployment as a plug-in of before fleets would answer: no fleet words
        def __getattr__(self, name: str) -> object:
            if name in ("deploys_fleet", "fleet_files"):
                raise AttributeError(name)
            return getattr(relay_deploy.DEPLOYMENT, name)

    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(FLEET)
    middleware.register(RELAY, BeforeFleets())  # type: ignore[arg-type]
    try:
        done = CliRunner().invoke(app, ["up", str(manifest), "--yes"])
    finally:
        middleware.register(RELAY, relay_deploy.DEPLOYMENT)
    assert done.exit_code == 1, done.output
    assert "robots: up deploys a fleet over the relay (ROS 1) and Zenoh (ROS 2) only; the relay middleware has no " \
           "per-robot access yet" in done.output
    assert "Traceback" not in done.output and list(_state_dir.iterdir()) == []
    assert CliRunner().invoke(app, ["plan", str(manifest)]).exit_code == 0
