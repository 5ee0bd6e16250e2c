"""Targets are plug-ins: one registered from here, with no change to fogiac/, runs through the
real CLI; every verb that takes a manifest takes a FogROS launch file too; targets without a
cloud answer doctor, refresh and sweep in one line."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from fogiac import targets
from fogiac.cli import app
from fogiac.errors import PlanError
from fogiac.manifest.schema import Manifest, load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Plan, Rule, SecurityGroup
from fogiac.plan.placement import Placement, Tags, host_per_node
from fogiac.state import read_json, stack_dir, write_json_atomic
from fogiac.lifecycle.events import OnEvent
from fogiac.targets.base import (
    Check,
    Created,
    Destroyed,
    DownOptions,
    Feature,
    Prepared,
    Reach,
    Refreshed,
    SweepOutcome,
    Target,
)
from tests.conftest import EXAMPLES
from tests.test_fogros_import import make_workspace

runner = CliRunner()


class FakeTarget:
    """A target that "creates" one record per host in a file of the stack's state folder (up --infra-only)."""

    name = "fake"
    summary = "records in a file, for tests"
    features = frozenset({Feature.CREATES_MACHINES, Feature.INFRA_ONLY})

    def __init__(self, *, open_to_world: bool = False) -> None:
        self.open_to_world = open_to_world

    def place(self, manifest: Manifest, *, stack: str, tags: Tags) -> Placement:
        hosts, node_hosts = host_per_node(manifest, stack=stack, tags=tags, address="fake.invalid")
        groups = (SecurityGroup("all", "open", (Rule("tcp", 22, 22, "0.0.0.0/0", "ssh"),), ()),) \
            if self.open_to_world else ()
        return Placement(hosts=hosts, node_hosts=node_hosts, mode="relay", connect_via="address",
                         security_groups=groups)

    def declare(self, plan: Plan) -> tuple[Mapping[str, Any], ...]:
        return tuple({"stack": "fake", "type": "fake:Machine", "name": h.name, "action": "create",
                      "inputs": {"machine": h.machine}} for h in plan.hosts)

    def _file(self, plan: Plan) -> Path:
        return stack_dir(plan.stack) / "fake.json"

    def ready(self, plan: Plan, *, verb: str) -> None:
        return None

    def prepare(self, plan: Plan, *, ssh_from: str | None) -> Prepared:
        return Prepared(plan=plan, question=f"Make {len(plan.hosts)} fake machine(s)?")

    def create(self, plan: Plan, prepared: Prepared, *, announce: Callable[[str], None],
               on_event: OnEvent | None) -> Created:
        write_json_atomic(self._file(plan), {h.name: h.machine for h in plan.hosts})
        return Created(plan=plan)

    def reach(self, plan: Plan, created: Created, *, announce: Callable[[str], None]) -> Reach:
        raise PlanError("fake machines cannot be reached")

    def access_from(self, description: Mapping[str, Any]) -> Any:
        raise PlanError("fake machines cannot be reached")

    def recorded(self, plan: Plan) -> bool:
        return self._file(plan).exists()

    def destroy(self, plan: Plan, opts: DownOptions) -> Destroyed:
        made = read_json(self._file(plan)) or {}
        self._file(plan).unlink(missing_ok=True)
        return Destroyed(deleted=tuple(sorted(made)))

    def forget(self, plan: Plan, *, keep_network: bool) -> None:
        return None

    def describe(self, plan: Plan, *, now: float) -> dict[str, Any]:
        made = read_json(self._file(plan)) or {}
        return {"hosts": [{"host": h, "machine": m} for h, m in sorted(made.items())]}

    def render_status(self, doc: Mapping[str, Any]) -> list[Any]:
        return [f"{h['host']} {h['machine']} fake" for h in doc["hosts"]] or [f"{doc['stack']}: nothing made"]

    def doctor(self, plan: Plan, *, ssh_from: str | None = None) -> list[Check]:
        return [Check("fake", True, "always ready")]

    def refresh(self, plan: Plan) -> list[Refreshed]:
        return [Refreshed("fake", True, "no changes")]

    def sweep(self, plan: Plan, *, dry_run: bool) -> SweepOutcome:
        return SweepOutcome()


@pytest.fixture
def fake() -> Iterator[FakeTarget]:
    target = FakeTarget()
    targets.register(target)
    yield target
    targets.unregister(target.name)


def run(*args: str) -> tuple[int, str]:
    result = runner.invoke(app, list(args))
    return result.exit_code, result.output


def test_a_fake_target_satisfies_the_protocol(fake: FakeTarget) -> None:
    assert isinstance(fake, Target)
    assert "fake" in targets.names()


def test_up_status_down_through_the_real_cli(fake: FakeTarget, tmp_path: Path) -> None:
    manifest = tmp_path / "fogiac.yaml"
    shutil.copy(EXAMPLES / "motion-planning.yaml", manifest)
    code, out = run("plan", str(manifest), "--target", "fake", "--json")
    assert code == 0, out
    assert [r["type"] for r in json.loads(out)["resources"]] == ["fake:Machine"]

    code, out = run("up", str(manifest), "--target", "fake", "--yes", "--infra-only")
    assert code == 0, out
    stack = compile_plan(load_manifest(manifest), target="fake").stack
    assert read_json(stack_dir(stack) / "fake.json") == {"planner": "c5.24xlarge"}

    code, out = run("status", str(manifest), "--target", "fake")
    assert code == 0, out
    assert out.splitlines() == ["planner c5.24xlarge fake"]
    assert json.loads(run("status", str(manifest), "--target", "fake", "--json")[1])["target"] == "fake"

    code, out = run("down", str(manifest), "--target", "fake", "--yes")
    assert code == 0, out
    assert out.splitlines()[-1] == f"{stack}: removed 1 (planner); nothing left"
    assert not (stack_dir(stack) / "fake.json").exists()


def test_an_unregistered_target_is_one_line_naming_the_registered_ones(tmp_path: Path) -> None:
    code, out = run("up", str(EXAMPLES / "minimal.yaml"), "--target", "fake", "--yes")
    assert code == 1
    assert out.strip() == "error: unknown target 'fake'; valid: aws, hosts, local"


def test_compile_refuses_world_ingress_whatever_the_target_places() -> None:
    targets.register(FakeTarget(open_to_world=True))
    try:
        with pytest.raises(PlanError, match=r"^security group 'all' would accept 0\.0\.0\.0/0 on port 22$"):
            compile_plan(load_manifest(EXAMPLES / "minimal.yaml"), target="fake")
    finally:
        targets.unregister("fake")


def _hosts_manifest(tmp_path: Path) -> Path:
    key = tmp_path / "id_ed25519"
    key.write_text("unused: refresh and sweep never connect\n")
    manifest = tmp_path / "lab.yaml"
    manifest.write_text(f"""\
name: lab
cloud:
  provider: hosts
  hosts:
    - name: gpu-box
      address: 127.0.0.1
      user: robot
      key: {key}
nodes:
  - name: planner
    machine: c5.4xlarge
    workload: motion_planning
""")
    return manifest


@pytest.mark.parametrize("verb", ["refresh", "sweep"])
@pytest.mark.parametrize("target", ["local", "hosts"])
def test_targets_without_a_cloud_say_so_in_one_line(verb: str, target: str, tmp_path: Path) -> None:
    manifest = _hosts_manifest(tmp_path)
    code, out = run(verb, str(manifest), "--target", target)
    assert code == 0, out
    assert out.splitlines() == [
        {"refresh": f"{target}: has no cloud account: nothing to refresh (target {target})",
         "sweep": f"target {target} has no cloud account: nothing to sweep; "
                  "`fogiac down` stops and removes what fogiac started"}[verb]]


def test_doctor_on_local_checks_this_machine_in_lines_not_a_traceback(tmp_path: Path) -> None:
    code, out = run("doctor", str(EXAMPLES / "motion-planning.yaml"), "--target", "local")
    lines = out.splitlines()
    # roscore, rospy, then what each workload node needs (issue 35 item 16: the planner's requirements)
    assert [line.split(":")[0] for line in lines] == [f"{'ok  ' if shutil.which('roscore') else 'FAIL'} roscore",
                                                       lines[1].split(":")[0], lines[2].split(":")[0]]
    assert lines[2].split(":")[0].endswith(" workload motion_planning (node planner)"), lines
    assert "Traceback" not in out and "boto" not in out
    assert code == (0 if all(line.startswith("ok") for line in lines) else 1)


@pytest.mark.parametrize("verb", [["validate"], ["plan"], ["plan", "--json"], ["cost"], ["graph", "--out"]])
def test_every_manifest_verb_takes_a_fogros_launch_file(verb: list[str], tmp_path: Path) -> None:
    launch = make_workspace(tmp_path)
    args = [verb[0], str(launch), *(["--json"] if "--json" in verb else [])]
    if verb[0] == "graph":
        args += ["--out", str(tmp_path / "g")]
    code, out = run(*args)
    assert code == 0, out
    if verb == ["validate"]:
        assert out.strip() == f"{launch}: valid (2 nodes, 2 hosts, target aws)"
    if verb == ["plan", "--json"]:
        assert sorted(h["name"] for h in json.loads(out)["hosts"]) == ["cloud-planner", "dexnet"]
