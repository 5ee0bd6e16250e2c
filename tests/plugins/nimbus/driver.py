"""Nimbus's answers to the lifecycle: its machines are made by its stack program through fogiac's one Pulumi
engine (under mocks that are nimbus's API) and are sandboxes here."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from fogiac.lifecycle.driver import (
    Check,
    Created,
    Destroyed,
    DownOptions,
    Feature,
    Machine,
    Prepared,
    Reach,
    Refreshed,
    SweepOutcome,
)
from fogiac.lifecycle.events import OnEvent
from fogiac.manifest.schema import Manifest
from fogiac.plan.model import Plan
from fogiac.plan.placement import Placement, Tags
from fogiac.provision import teardown
from fogiac.provision.local import PORTS_FILE, LocalAccess, local_access, local_ports, sandbox_root
from fogiac.pulumi_engine import offline
from fogiac.pulumi_engine.engine import Engine
from fogiac.state import stack_dir
from tests.plugins.nimbus import placement
from tests.plugins.nimbus.program import LAYER, Cloud, programs, project

CLOUD_FILE = "nimbus-cloud.json"  # what the nimbus API holds for the stack


class NimbusTarget:
    name = "nimbus"
    summary = "nimbus machines (a cloud defined in the tests: sandboxes behind a stack program)"
    features = frozenset({Feature.CREATES_MACHINES, Feature.PROVISIONS})

    def _cloud(self, plan: Plan) -> Cloud:
        return Cloud(stack_dir(plan.stack) / CLOUD_FILE)

    def place(self, manifest: Manifest, *, stack: str, tags: Tags) -> Placement:
        return placement.place(manifest, stack=stack, tags=tags)

    def declare(self, plan: Plan) -> tuple[Mapping[str, Any], ...]:
        return offline.declare(plan, project(plan), programs(plan), answers=Cloud(None)).rows()

    def ready(self, plan: Plan, *, verb: str) -> None:
        return None

    def prepare(self, plan: Plan, *, ssh_from: str | None) -> Prepared:
        return Prepared(plan=plan, question=f"Create {len(plan.hosts)} nimbus machine(s) in {plan.region} "
                                            f"(${plan.hourly_usd:.2f}/h)?", summary=(f"nimbus {plan.region}",))

    def create(self, plan: Plan, prepared: Prepared, *, announce: Callable[[str], None],
               on_event: OnEvent | None) -> Created:
        outputs = Engine(project(plan), on_event=on_event, mocks=self._cloud(plan)).up(programs(plan))
        ids = outputs[LAYER]["machines"]
        return Created(plan=plan, outputs={"machines": ids},
                       machines=tuple(Machine(h.name, ids[h.name], h.machine, "127.0.0.1") for h in plan.hosts))

    def reach(self, plan: Plan, created: Created, *, announce: Callable[[str], None]) -> Reach:
        ports = local_ports(plan, state_dir=stack_dir(plan.stack))
        return Reach(access=local_access(plan, state_dir=stack_dir(plan.stack)), ports=ports,
                     connect={h: f"127.0.0.1:{p.relay_port}" for h, p in ports.items()})

    def access_from(self, description: Mapping[str, Any]) -> LocalAccess:
        return LocalAccess.from_description(description)  # a nimbus machine is a sandbox here

    def recorded(self, plan: Plan) -> bool:
        return (stack_dir(plan.stack, create=False) / CLOUD_FILE).exists()

    def destroy(self, plan: Plan, opts: DownOptions) -> Destroyed:
        """Terminating a nimbus machine stops everything on it and removes its disk (the sandbox)."""
        folder = stack_dir(plan.stack)
        made = self._cloud(plan).machines()
        report = teardown(plan, hosts=local_access(plan, state_dir=folder), state_dir=folder)
        (folder / CLOUD_FILE).unlink(missing_ok=True)
        left = [f"sandbox {p}" for p in sorted(sandbox_root(folder).glob("*")) if p.is_dir()]
        return Destroyed(errors=tuple(o.error or o.host for o in report.failed), left=tuple(left),
                         deleted=tuple(f"machine {entry['id']}" for entry in made.values()))

    def forget(self, plan: Plan, *, keep_network: bool) -> None:
        (sandbox_root(stack_dir(plan.stack)) / PORTS_FILE).unlink(missing_ok=True)

    def describe(self, plan: Plan, *, now: float) -> dict[str, Any]:
        made = self._cloud(plan).machines()
        return {"hosts": [{"host": name.removeprefix(f"{plan.stack}-"), "id": entry["id"], "shape": entry["shape"],
                           "region": entry["region"]} for name, entry in sorted(made.items())]}

    def render_status(self, doc: Mapping[str, Any]) -> list[Any]:
        return [f"{h['host']}: {h['id']} {h['shape']} in {h['region']}" for h in doc["hosts"]] or \
            [f"{doc['stack']}: no nimbus machines"]

    def doctor(self, plan: Plan, *, ssh_from: str | None = None) -> list[Check]:
        return [Check("nimbus", True, "the nimbus API is a file here")]

    def refresh(self, plan: Plan) -> list[Refreshed]:
        return [Refreshed("nimbus", True, f"{len(self._cloud(plan).machines())} machine(s)")]

    def sweep(self, plan: Plan, *, dry_run: bool) -> SweepOutcome:
        return SweepOutcome(note="nimbus keeps no resources outside the stack's record")


NIMBUS = NimbusTarget()


def sandbox(plan: Plan, host: str) -> Path:
    return sandbox_root(stack_dir(plan.stack)) / host
