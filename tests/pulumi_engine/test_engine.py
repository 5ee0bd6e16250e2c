"""The engine without a cloud: layer naming, events, failures in one line, the Automation API's options,
and ``up`` under Pulumi's mocks (a cloud's API answered in-process), with a program of its own here."""

from __future__ import annotations

import gc
import os
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pulumi
import pytest
from pulumi.automation import events

from fogiac.pulumi_engine.errors import EngineError
from fogiac.lifecycle.events import Progress
from fogiac.pulumi_engine import engine, workspace
from fogiac.pulumi_engine.events import Timers
from fogiac.pulumi_engine.project import Earlier, Program, Project
from fogiac.state import stack_dir

THING = "box:shelf:Thing"


def test_layers_are_named_per_manifest_environment_and_layer() -> None:
    project = Project("fogiac", "minimal-dev", ("network", "compute"))
    assert project.layer_stack("network") == "minimal-dev-network"
    assert Project("fogiac", "minimal-prod", ("network", "compute")).layer_stack("compute") == "minimal-prod-compute"
    with pytest.raises(EngineError, match=r"^unknown layer 'vpn'; valid: network, compute$"):
        project.layer_stack("vpn")


def _step(op: str, urn: str, typ: str) -> events.StepEventMetadata:
    return events.StepEventMetadata(op=events.OpType(op), urn=urn, type=typ, provider="")


def test_timers_follow_engine_events() -> None:
    now = [100.0]
    timers = Timers(clock=lambda: now[0])
    vpc = "urn:pulumi:s::fogiac::fogiac:aws:Network$aws:ec2/vpc:Vpc::m-dev-vpc"
    sub = "urn:pulumi:s::fogiac::fogiac:aws:Network$aws:ec2/subnet:Subnet::m-dev-subnet-hosts"
    feed = [
        events.EngineEvent(1, 0, resource_pre_event=events.ResourcePreEvent(
            _step("create", "urn:pulumi:s::fogiac::pulumi:pulumi:Stack::fogiac-s", "pulumi:pulumi:Stack"))),
        events.EngineEvent(2, 0, resource_pre_event=events.ResourcePreEvent(_step("create", vpc, "aws:ec2/vpc:Vpc"))),
        events.EngineEvent(3, 0, resource_pre_event=events.ResourcePreEvent(_step("same", sub, "aws:ec2/subnet:Subnet"))),
    ]
    for event in feed:
        timers(event)
    assert list(timers.rows) == [vpc]
    assert [r.name for r in timers.running()] == ["m-dev-vpc"]
    now[0] = 103.5
    assert timers.rows[vpc].elapsed(now[0]) == 3.5
    timers(events.EngineEvent(4, 0, res_outputs_event=events.ResOutputsEvent(_step("create", vpc, "aws:ec2/vpc:Vpc"))))
    now[0] = 200.0
    assert timers.rows[vpc].elapsed(now[0]) == 3.5 and timers.running() == []
    inst = "urn:pulumi:s::fogiac::aws:ec2/instance:Instance::m-dev-host-a"
    timers(events.EngineEvent(5, 0, resource_pre_event=events.ResourcePreEvent(
        _step("create", inst, "aws:ec2/instance:Instance"))))
    timers(events.EngineEvent(6, 0, res_op_failed_event=events.ResOpFailedEvent(
        _step("create", inst, "aws:ec2/instance:Instance"), status=1, steps=1)))
    timers(events.EngineEvent(7, 0, diagnostic_event=events.DiagnosticEvent(
        message="creating instance: InsufficientInstanceCapacity\n", color="never", severity="error")))
    assert timers.rows[inst].failed
    assert timers.diagnostics == ["creating instance: InsufficientInstanceCapacity"]


def test_engine_failures_become_one_line() -> None:
    from pulumi.automation import CommandError, CommandResult

    err = CommandError(CommandResult(stdout="Updating (x)\n", code=255, stderr=(
        "Updating...\n  error: creating EC2 Instance: InsufficientInstanceCapacity\n\n")))
    assert engine._last_error(err) == "error: creating EC2 Instance: InsufficientInstanceCapacity"
    assert engine._changes({"create": 12, "same": 0, "update": 1}) == "create 12, update 1"
    assert engine._changes({}) == "no changes"


def test_no_pulumi_on_import() -> None:
    code = ("import sys, fogiac.pulumi_engine.engine, fogiac.pulumi_engine.offline, fogiac.pulumi_engine.terraform;"
            "print(sorted(m for m in ('pulumi', 'pulumi.automation') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={**os.environ, "PYTHONPATH": str(Path(__file__).parents[2])})
    assert out.stdout.strip() == "[]"


def test_workspace_options_carry_the_project_and_its_config(pinned_pulumi: Path,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("PULUMI_CONFIG_PASSPHRASE", raising=False)
    monkeypatch.delenv("PULUMI_CONFIG_PASSPHRASE_FILE", raising=False)
    project = Project("shelf", "box-dev", ("base", "top"), {"box:region": "moon-1"})
    opts = engine.Engine(project)._options()
    backend = (stack_dir("box-dev") / "pulumi").as_uri()
    assert opts.secrets_provider == "passphrase"
    assert opts.project_settings.name == "shelf" and opts.project_settings.backend.url == backend
    assert opts.env_vars["PULUMI_BACKEND_URL"] == backend
    assert opts.env_vars["PULUMI_CONFIG_PASSPHRASE"] == workspace.passphrase("box-dev")


def test_destroy_and_refresh_of_a_never_applied_project_write_nothing(pinned_pulumi: Path) -> None:
    project = Project("shelf", "never-dev", ("base", "top"))
    assert engine.Engine(project).destroy() == []
    assert engine.Engine(project).refresh() == []
    assert not stack_dir("never-dev", create=False).exists()


# -- up under mocks: a two-layer program whose second layer reads the first's outputs --------------


class Thing(pulumi.CustomResource):
    def __init__(self, name: str, props: Mapping[str, Any]) -> None:
        super().__init__(THING, name, dict(props))


class Shelf(pulumi.runtime.Mocks):
    """A cloud's API in-process: makes each thing it is asked for (``boom`` fails) and remembers it."""

    def __init__(self) -> None:
        self.made: list[tuple[str, dict[str, Any]]] = []

    def new_resource(self, args: pulumi.runtime.MockResourceArgs) -> tuple[str, dict[str, Any]]:
        if args.name == "boom":
            raise RuntimeError("the shelf is full")
        self.made.append((args.name, dict(args.inputs)))
        return f"id-{args.name}", dict(args.inputs)

    def call(self, args: pulumi.runtime.MockCallArgs) -> dict[str, Any]:
        return {}


def programs(*, top: str = "b") -> Any:
    def build(earlier: Earlier) -> dict[str, Program]:
        def base() -> None:
            pulumi.export("a_id", Thing("a", {"size": 2}).id)

        def upper() -> None:
            pulumi.export("b_id", Thing(top, {"after": earlier("base")["a_id"]}).id)

        return {"base": base, "top": upper}

    return build


def test_up_under_mocks_feeds_each_layer_the_outputs_before_and_streams_progress(no_pulumi: None) -> None:
    shelf, seen = Shelf(), []
    project = Project("shelf", "box-dev", ("base", "top"))
    outputs = engine.Engine(project, on_event=seen.append, mocks=shelf).up(programs())
    assert outputs == {"base": {"a_id": "id-a"}, "top": {"b_id": "id-b"}}
    assert shelf.made == [("a", {"size": 2}), ("b", {"after": "id-a"})]
    assert seen == [Progress("start", f"base::{THING}::a", "a", THING, "create"), Progress("done", f"base::{THING}::a"),
                    Progress("start", f"top::{THING}::b", "b", THING, "create"), Progress("done", f"top::{THING}::b")]
    assert not stack_dir("box-dev", create=False).exists()  # the mocks are the cloud's record: no backend


def _failed_up(seen: list[Progress]) -> str:
    try:
        engine.Engine(Project("shelf", "box-dev", ("base", "top")), on_event=seen.append,
                      mocks=Shelf()).up(programs(top="boom"))
    except RuntimeError as err:
        return str(err)
    return "no failure"


def test_a_failure_under_mocks_is_the_failed_resource(no_pulumi: None) -> None:
    seen: list[Progress] = []
    assert _failed_up(seen) == "the shelf is full"
    # The failed run's futures sit in reference cycles; finalised later, by a collection inside ast.parse
    # (pytest rewriting a module it imports late), they upset CPython 3.11's recursion count. Now instead.
    gc.collect()
    assert seen[-2:] == [Progress("start", f"top::{THING}::boom", "boom", THING, "create"),
                         Progress("failed", f"top::{THING}::boom")]
