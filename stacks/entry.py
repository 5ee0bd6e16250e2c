"""What plain ``pulumi preview``/``up`` in ``stacks/`` runs: stack config in, one layer declared.

The engine drives the same programs through the Automation API; this entry exists so a user's
CI can run the stock Pulumi CLI on a manifest. Config (project ``fogiac``):

- ``fogiac:manifest``     path to fogiac.yaml (relative to ``stacks/``)
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

from fogiac.errors import PlanError
from fogiac.plan import OPERATOR, Plan

LAYERS = ("network", "compute")
SSH_KEY = "id_ed25519"  # under stack_dir(stack)/"ssh": private 0600, public beside it (.pub)


@dataclass(frozen=True)
class StackConfig:
    manifest: Path
    layer: str
    environment: str
    target: str
    ssh_from: tuple[str, ...]
    network_stack: str | None


def read_config(get: Callable[[str], str | None], *, base: Path) -> StackConfig:
    """Parse the stack config through ``get`` (pulumi.Config("fogiac").get in a program)."""
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


def load_or_create_ssh_key(directory: Path) -> str:
    """The stack's ed25519 public key (OpenSSH format), made on first use; private key 0600."""
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

    from fogiac.certs import write_private

    public = directory / f"{SSH_KEY}.pub"
    private = directory / SSH_KEY
    if private.exists() and public.exists():
        return public.read_text().strip()
    key = Ed25519PrivateKey.generate()
    write_private(
        private,
        key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.OpenSSH, serialization.NoEncryption()),
    )
    text = key.public_key().public_bytes(serialization.Encoding.OpenSSH, serialization.PublicFormat.OpenSSH).decode()
    public.write_text(f"{text} fogiac\n")
    return public.read_text().strip()


def main(*, base: Path | None = None) -> None:
    """Declare the configured layer; called by ``stacks/__main__.py`` inside a Pulumi program."""
    import pulumi

    from fogiac.certs import load_or_create_bundle
    from fogiac.compile import compile_plan
    from fogiac.manifest import load_manifest
    from fogiac.state import stack_dir
    from stacks.program import compute_program, network_program

    config = read_config(pulumi.Config("fogiac").get, base=base or Path.cwd())
    plan = compile_plan(load_manifest(config.manifest), target=config.target, environment=config.environment)
    region = pulumi.Config("aws").get("region")
    if region is not None and region != plan.region:
        raise PlanError(f"aws:region is {region} but the manifest says {plan.region}; make them agree")
    if config.layer == "network":
        certs = load_or_create_bundle(plan.stack, stack_dir(plan.stack) / "certs")
        network_program(plan, certs=certs, operator_cidrs=operator_cidrs(plan, config))
        return
    if not config.network_stack:
        raise PlanError("the compute layer needs fogiac:networkStack (the network stack's name)")
    ref = pulumi.StackReference(config.network_stack)
    network: dict[str, Any] = {key: ref.require_output(key) for key in ("subnet_ids", "security_group_ids")}
    public_key = load_or_create_ssh_key(stack_dir(plan.stack) / "ssh")
    compute_program(plan, network=network, public_key_openssh=public_key)

