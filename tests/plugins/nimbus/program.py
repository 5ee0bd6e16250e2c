"""Nimbus's stack program: one ``nimbus:compute:Machine`` per planned host, run under Pulumi's mocks.

The mocks are the nimbus cloud's API here: ``Cloud`` keeps the machines it was asked for in a JSON
file (the cloud's own record, as a provider's API would), so ``up`` creates, a second ``up`` finds
them, and ``down`` deletes them.
"""

from __future__ import annotations

import uuid
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pulumi
from pulumi.runtime import mocks as pulumi_mocks
from pulumi.runtime.stack import run_pulumi_func
from pulumi.runtime.sync_await import _sync_await

from fogiac.plan.model import Plan
from fogiac.state import read_json, write_json_atomic

MACHINE = "nimbus:compute:Machine"


class Machine(pulumi.CustomResource):
    def __init__(self, name: str, props: Mapping[str, Any], opts: pulumi.ResourceOptions | None = None) -> None:
        super().__init__(MACHINE, name, dict(props), opts)


def program(plan: Plan) -> dict[str, pulumi.Output[Any]]:
    out: dict[str, pulumi.Output[Any]] = {}
    for host in plan.hosts:
        made = Machine(f"{plan.stack}-{host.name}", {"shape": host.machine, "region": plan.region,
                                                     "tags": dict(host.tags)})
        out[host.name] = made.id
    return out


class Cloud(pulumi_mocks.Mocks):
    """The nimbus API: machines by logical name in ``path``; ``create`` reuses one that is there."""

    def __init__(self, path: Path | None) -> None:
        self.path = path
        self.declared: list[dict[str, Any]] = []

    def machines(self) -> dict[str, Any]:
        return (read_json(self.path) or {}) if self.path is not None else {}

    def new_resource(self, args: pulumi_mocks.MockResourceArgs) -> tuple[str | None, dict[str, Any]]:
        self.declared.append({"type": args.typ, "name": args.name, "inputs": dict(args.inputs)})
        if self.path is None:  # a plan: nothing is made
            return f"{args.name}-id", dict(args.inputs)
        made = self.machines()
        entry = made.get(args.name) or {"id": f"nb-{uuid.uuid4().hex[:10]}", **dict(args.inputs)}
        write_json_atomic(self.path, {**made, args.name: entry})
        return entry["id"], dict(args.inputs)

    def call(self, args: pulumi_mocks.MockCallArgs) -> tuple[dict[str, Any], list[tuple[str, str]] | None]:
        return {}, None


def run(plan: Plan, cloud: Cloud) -> dict[str, str]:
    """Run the program against ``cloud``; host -> machine id."""
    pulumi.runtime.set_mocks(cloud, project="nimbus", stack=plan.stack, preview=cloud.path is None)
    found: dict[str, str] = {}

    def body() -> Any:
        outputs = program(plan)
        return pulumi.Output.all(**outputs).apply(found.update)

    _sync_await(run_pulumi_func(lambda: _sync_await(pulumi.Output.from_input(body()).future())))
    return found
