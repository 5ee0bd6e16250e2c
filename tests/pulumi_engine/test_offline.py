"""The offline preview without a cloud: a program of its own here, declared under the engine's mocks."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pulumi

from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.pulumi_engine.offline import SECRET, Placeholders, declare, redact
from fogiac.pulumi_engine.project import Earlier, Program, Project

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_redact() -> None:
    wrapped = {"4dabf18193072939515e22adb298388d": "1b47061264138c4ac30d75fd1eb44270", "value": "hunter2"}
    pem = "-----BEGIN PRIVATE KEY-----\nMIIE\n-----END PRIVATE KEY-----\n"
    assert redact({"b": wrapped, "a": [pem, 22.0, 1.5, True]}) == {"a": [SECRET, 22, 1.5, True], "b": SECRET}


class Crate(pulumi.ComponentResource):
    def __init__(self, name: str) -> None:
        super().__init__("box:index:Crate", name)
        child = pulumi.ResourceOptions(parent=self)
        self.lid = pulumi.CustomResource("box:shelf:Lid", f"{name}-lid",
                                         {"size": 3.0, "key": pulumi.Output.secret("k")}, child)
        self.register_outputs({})


def programs(earlier: Earlier) -> dict[str, Program]:
    def base() -> None:
        crate = Crate("c")
        pulumi.export("lid", crate.lid.id)
        made = pulumi.CustomResource("box:shelf:Lid", "c-made", {"size": 1, "madeAt": None})  # madeAt: an output
        pulumi.export("made", made.madeAt)  # type: ignore[attr-defined]

    def top() -> None:
        pulumi.CustomResource("box:shelf:Label", "l", {"on": earlier("base")["lid"]})

    return {"base": base, "top": top}


def test_declare_records_each_layer_in_order_with_the_clouds_placeholders() -> None:
    plan = compile_plan(load_manifest(EXAMPLES / "minimal.yaml"))
    found = declare(plan, Project("box", plan.stack, ("base", "top")), programs,
                    answers=Placeholders(computed={"box:shelf:Lid": ("madeAt",)}))
    assert [(r.stack, r.type, r.name, r.custom) for r in found.resources] == [
        ("base", "box:index:Crate", "c", False), ("base", "box:shelf:Lid", "c-lid", True),
        ("base", "box:shelf:Lid", "c-made", True), ("top", "box:shelf:Label", "l", True)]
    assert found.rows()[0] == {"stack": "base", "type": "box:shelf:Lid", "name": "c-lid", "action": "create",
                               "inputs": {"key": SECRET, "size": 3}}
    assert found.rows()[-1]["inputs"] == {"on": "<c-lid.id>"}  # the earlier layer's output, as the mocks answered
    assert dict(found.outputs["base"]) == {"lid": "<c-lid.id>", "made": "<c-made.madeAt>"}


class Answers(pulumi.runtime.Mocks):
    """Any Pulumi mocks answer; the engine records what was declared all the same."""

    def new_resource(self, args: pulumi.runtime.MockResourceArgs) -> tuple[str, dict[str, Any]]:
        return f"{args.name}-1", dict(args.inputs, madeAt="today")

    def call(self, args: pulumi.runtime.MockCallArgs) -> Mapping[str, Any]:
        return {}


def test_declare_under_a_clouds_own_mocks() -> None:
    plan = compile_plan(load_manifest(EXAMPLES / "minimal.yaml"))
    found = declare(plan, Project("box", plan.stack, ("base", "top")), programs, answers=Answers())
    assert [r.name for r in found.resources if r.custom] == ["c-lid", "c-made", "l"]
    assert dict(found.outputs["base"]) == {"lid": "c-lid-1", "made": "today"}
    assert found.rows()[-1]["inputs"] == {"on": "c-lid-1"}
