"""Nimbus's stack program: one ``nimbus:compute:Machine`` per planned host, declared through fogiac's one
Pulumi engine (:mod:`fogiac.pulumi_engine`), as aws's programs are.

The engine runs it under Pulumi's mocks, which are the nimbus cloud's API here: ``Cloud`` keeps
the machines it was asked for in a JSON file (the cloud's own record, as a provider's API would),
so ``up`` creates, a second ``up`` finds them, and ``down`` deletes them. For ``plan`` the engine's
offline preview runs the same program against ``Cloud(None)``, which makes nothing.
"""

from __future__ import annotations

import uuid
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pulumi
from pulumi.runtime import mocks as pulumi_mocks

from fogiac.plan.model import Plan
from fogiac.pulumi_engine.project import Earlier, Program, Programs, Project
from fogiac.state import read_json, write_json_atomic

MACHINE = "nimbus:compute:Machine"
LAYER = "machines"  # nimbus's one layer: no network of its own


class Machine(pulumi.CustomResource):
    def __init__(self, name: str, props: Mapping[str, Any], opts: pulumi.ResourceOptions | None = None) -> None:
        super().__init__(MACHINE, name, dict(props), opts)


def project(plan: Plan) -> Project:
    return Project("nimbus", plan.stack, (LAYER,), {"nimbus:region": plan.region})


def programs(plan: Plan) -> Programs:
    """The program of nimbus's one layer: a machine per host, their ids exported as ``machines``."""

    def machines() -> None:
        made = {host.name: Machine(f"{plan.stack}-{host.name}", {"shape": host.machine, "region": plan.region,
                                                                  "tags": dict(host.tags)}).id
                for host in plan.hosts}
        pulumi.export("machines", made)

    def build(earlier: Earlier) -> dict[str, Program]:
        return {LAYER: machines}

    return build


class Cloud(pulumi_mocks.Mocks):
    """The nimbus API: machines by logical name in ``path``; ``create`` reuses one that is there."""

    def __init__(self, path: Path | None) -> None:
        self.path = path

    def machines(self) -> dict[str, Any]:
        return (read_json(self.path) or {}) if self.path is not None else {}

    def new_resource(self, args: pulumi_mocks.MockResourceArgs) -> tuple[str | None, dict[str, Any]]:
        if self.path is None:  # a plan: nothing is made
            return f"{args.name}-id", dict(args.inputs)
        made = self.machines()
        entry = made.get(args.name) or {"id": f"nb-{uuid.uuid4().hex[:10]}", **dict(args.inputs)}
        write_json_atomic(self.path, {**made, args.name: entry})
        return entry["id"], dict(args.inputs)

    def call(self, args: pulumi_mocks.MockCallArgs) -> tuple[dict[str, Any], list[tuple[str, str]] | None]:
        return {}, None
