"""What plain ``pulumi preview``/``up`` in ``stacks/aws/`` runs: stack config in, one layer declared.

The engine drives the same programs through the Automation API; this entry exists so a user's
CI can run the stock Pulumi CLI on a manifest. Config (project ``fogiac``, :data:`stacks.aws.PROJECT`):

- ``fogiac:manifest``     path to fogiac.yaml (relative to ``stacks/aws/``)
- ``fogiac:layer``        ``network`` or ``compute``
- ``fogiac:environment``  default ``dev``;  ``fogiac:target`` default ``aws``
- ``fogiac:sshFrom``      the operator's CIDRs, comma-separated (needed when ssh_from is auto)
- ``fogiac:networkStack`` compute only: the network stack's name for a StackReference
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pulumi

from fogiac.certs import load_or_create_bundle, load_or_create_ssh_key
from fogiac.errors import PlanError
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import OPERATOR, Plan
from fogiac.state import StackState
from stacks.aws import LAYERS, PROJECT
from stacks.aws.program import layer_programs


@dataclass(frozen=True)
class StackConfig:
    manifest: Path
    layer: str
    environment: str
    target: str
    ssh_from: tuple[str, ...]
    network_stack: str | None


def read_config(get: Callable[[str], str | None], *, base: Path) -> StackConfig:
    """Parse the stack config through ``get`` (``pulumi.Config(PROJECT).get`` in a program)."""
    manifest = get("manifest")
    if not manifest:
        raise PlanError("stack config fogiac:manifest is not set; run: pulumi config set fogiac:manifest PATH")
    layer = get("layer") or "network"
    if layer not in LAYERS:
        raise PlanError(f"fogiac:layer is {layer!r}; valid: {', '.join(LAYERS)}")
    ssh_from = tuple(c.strip() for c in (get("sshFrom") or "").split(",") if c.strip())
    return StackConfig(
        manifest=(base / manifest).resolve(),
        layer=layer,
        environment=get("environment") or "dev",
        target=get("target") or "aws",
        ssh_from=ssh_from,
        network_stack=get("networkStack"),
    )


def operator_cidrs(plan: Plan, config: StackConfig) -> tuple[str, ...]:
    if OPERATOR in plan.ssh_from and not config.ssh_from:
        raise PlanError(
            "the manifest's ssh_from is auto; set your address: pulumi config set fogiac:sshFrom 203.0.113.7/32"
        )
    return config.ssh_from


def main(*, base: Path | None = None) -> None:
    """Declare the configured layer; called by ``stacks/aws/__main__.py`` inside a Pulumi program."""
    config = read_config(pulumi.Config(PROJECT).get, base=base or Path.cwd())
    plan = compile_plan(load_manifest(config.manifest), target=config.target, environment=config.environment)
    region = pulumi.Config("aws").get("region")
    if region is not None and region != plan.region:
        raise PlanError(f"aws:region is {region} but the manifest says {plan.region}; make them agree")
    if config.layer == "compute" and not config.network_stack:
        raise PlanError("the compute layer needs fogiac:networkStack (the network stack's name)")

    def network_outputs() -> dict[str, Any]:
        ref = pulumi.StackReference(str(config.network_stack))
        return {key: ref.require_output(key) for key in ("subnet_ids", "security_group_ids")}

    state = StackState(plan.stack)
    state.ensure()
    programs = layer_programs(
        plan, certs=load_or_create_bundle(plan.stack, state.certs),
        operator_cidrs=operator_cidrs(plan, config) if config.layer == "network" else (),
        public_key_openssh=load_or_create_ssh_key(state.ssh_dir), network_outputs=network_outputs)
    programs[config.layer]()
