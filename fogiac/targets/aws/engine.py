"""The aws stacks through fogiac's one Pulumi engine (:mod:`fogiac.pulumi_engine`): two stacks per manifest
and environment, network then compute.

What is aws's here is what the engine is fed: the programs from ``stacks/aws/`` (with the stack's
certificates and SSH key, made on first use), the stack config (``aws:region``), which outputs
name cloud ids, and the wiring of compute to network's outputs. Network goes up before compute
(compute is fed network's outputs) and comes down after it. Nothing here imports pulumi at import.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from fogiac.certs import SSH_KEY, load_or_create_bundle, load_or_create_ssh_key
from fogiac.lifecycle.events import OnEvent
from fogiac.plan.model import Plan
from fogiac.pulumi_engine.engine import Engine as PulumiEngine
from fogiac.pulumi_engine.engine import LayerResult
from fogiac.pulumi_engine.project import Earlier, Program, Project
from fogiac.pulumi_engine.workspace import backend_dir
from fogiac.state import StackState, read_json
from fogiac.targets.aws.sdk import need
from stacks.aws import LAYERS, PROJECT

OUTPUTS_FILE = "outputs.json"
SSH_KEY_FILE = Path(StackState.SSH) / SSH_KEY  # where stacks/aws/entry.py (plain pulumi up) keeps it
CERTS_DIR = StackState.CERTS
VPN_NOTICE = ("The Client VPN endpoint's subnet association takes about 10 minutes to create "
              "(and again to delete); its resources wait up to 30 minutes.")


def stack_config(plan: Plan) -> dict[str, str]:
    return {"aws:region": plan.region}


def project(plan: Plan) -> Project:
    """The aws Pulumi project of ``plan``'s stack: stacks/aws/Pulumi.yaml's name, its two layers, its region."""
    return Project(PROJECT, plan.stack, LAYERS, stack_config(plan))


def ssh_public_key(stack: str) -> str:
    """The stack's SSH key (ed25519, private half 0600), created on first use.

    Kept where ``stacks/aws/entry.py`` (plain ``pulumi up``) keeps it, so both paths use one key.
    """
    state = StackState(stack)
    state.ensure()
    return load_or_create_ssh_key(state.ssh_dir)


def known_ids(stack: str) -> frozenset[str]:
    """Every cloud id fogiac's state knows for ``stack`` (outputs and Pulumi checkpoints).

    With a shared store the checkpoints are read from its bucket, every stack's: Pulumi keeps them there,
    not on this machine, so a second member's preflight must not take the first member's resources for
    strangers (and tell them to sweep what another member runs)."""
    ids: set[str] = set()
    state = StackState(stack)

    def walk(value: Any) -> None:
        if isinstance(value, Mapping):
            for key, item in value.items():
                if key in {"id", "vpc_id", "instance_id", "vpn_endpoint_id"} and isinstance(item, str):
                    ids.add(item)
                walk(item)
        elif isinstance(value, list):
            for item in value:
                walk(item)

    walk(read_json(state.target_file(OUTPUTS_FILE)))
    shared = getattr(state.store, "pulumi_checkpoints", None)
    if shared is not None:  # the lab's bucket: every member's stacks, wherever they were applied from
        for _, checkpoint in shared():
            walk(checkpoint)
    for checkpoint in backend_dir(stack, create=False).glob(".pulumi/stacks/**/*.json") if state.exists() else ():
        walk(read_json(checkpoint))
    return frozenset(ids)


class Engine:
    """One manifest's aws layers through the one engine (the Pulumi CLI does the work)."""

    def __init__(self, plan: Plan, *, on_event: OnEvent | None = None) -> None:
        self.plan = plan
        self.engine = PulumiEngine(project(plan), on_event=on_event)  # fails with the install line first
        need("pulumi.automation")  # a missing SDK names the aws extra, before the engine asks for it

    def programs(self, *, operator_cidrs: tuple[str, ...],
                 network_outputs: Callable[[], Mapping[str, Any]]) -> dict[str, Program]:
        stack = self.plan.stack
        return need("stacks.aws.program").layer_programs(
            self.plan, certs=load_or_create_bundle(stack, StackState(stack).certs),
            operator_cidrs=operator_cidrs, public_key_openssh=ssh_public_key(stack), network_outputs=network_outputs)

    def _programs(self, operator_cidrs: tuple[str, ...]) -> Callable[[Earlier], Mapping[str, Program]]:
        return lambda earlier: self.programs(operator_cidrs=operator_cidrs, network_outputs=lambda: earlier("network"))

    def preview(self, *, operator_cidrs: tuple[str, ...]) -> list[LayerResult]:
        def pending(layer: str, outputs: Mapping[str, Mapping[str, Any]]) -> str | None:
            waits = layer == "compute" and not outputs.get("network", {}).get("subnet_ids")
            return "previewed once the network stack exists" if waits else None

        return self.engine.preview(self._programs(operator_cidrs), pending=pending)

    def up(self, *, operator_cidrs: tuple[str, ...]) -> dict[str, Mapping[str, Any]]:
        """Network, then compute fed network's outputs; raises EngineError naming the failed layer."""
        return self.engine.up(self._programs(operator_cidrs))

    def destroy(self, *, layers: tuple[str, ...] = ("compute", "network")) -> list[str]:
        """Destroy ``layers`` in that order, continuing past errors; return one line per failure."""
        return self.engine.destroy(layers=layers)

    def refresh(self) -> list[LayerResult]:
        return self.engine.refresh()
