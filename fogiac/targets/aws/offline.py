"""The aws offline plan: its stack programs under the engine's mocks (:mod:`fogiac.pulumi_engine.offline`).

No credentials, no Pulumi CLI, no files written: ``fogiac plan`` shows the exact resources a
manifest implies, with the inputs pulumi_aws would send. What is aws's here is what the mocks
answer for it (the attributes AWS computes, the AMI lookup) and the stand-ins for what is made only
at ``up``: the certificates and the SSH key appear as ``<...>`` placeholders, never generated.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

from fogiac.certs import Bundle, KeyPair
from fogiac.plan.model import OPERATOR_PLACEHOLDER, Plan
from fogiac.pulumi_engine import offline
from fogiac.pulumi_engine.offline import OfflinePlan
from fogiac.pulumi_engine.project import Earlier, Program, Project
from fogiac.targets.aws.sdk import need
from stacks.aws import LAYERS, PROJECT

# Attributes AWS computes that the programs read or export (``arn`` on every resource).
_COMPUTED: dict[str, tuple[str, ...]] = {
    "aws:ec2/instance:Instance": ("publicIp", "privateIp", "publicDns"),
    "aws:ec2clientvpn/endpoint:Endpoint": ("dnsName",),
}


def _newest_ami(args: Mapping[str, Any]) -> dict[str, Any]:
    pattern = next((f["values"][0] for f in args.get("filters", []) if f["name"] == "name"), "?")
    ami = f"<newest AMI named {pattern!r} by {','.join(args.get('owners', []))}>"
    return {"id": ami, "imageId": ami, "name": pattern, "architecture": "x86_64"}


def _caller(args: Mapping[str, Any]) -> dict[str, Any]:
    return {"id": "<account>", "accountId": "<account>", "arn": "<caller>", "userId": "<caller>"}


PLACEHOLDERS = offline.Placeholders(computed=_COMPUTED, always=("arn",), calls={
    "aws:ec2/getAmi:getAmi": _newest_ami, "aws:index/getCallerIdentity:getCallerIdentity": _caller})


def offline_bundle(stack: str) -> Bundle:
    """Stand-ins for the stack's certificates: a plan must neither write nor show real keys.

    Generating three RSA 2048 keys would cost more than the rest of a plan, and their bodies
    would change on every run; the certificates are made (once, persisted) at ``up``.
    """

    def pair(role: str) -> KeyPair:
        return KeyPair(f"<{role} certificate of {stack}, made at up>".encode(), f"<{role} key>".encode())

    return Bundle(ca=pair("CA"), vpn=pair("VPN endpoint"), client=pair("client"))


def offline_public_key(stack: str) -> str:
    return f"<ssh-ed25519 public key of {stack}, made at up>"


def declare(plan: Plan, *, mocks: Any | None = None) -> OfflinePlan:
    """Run the network then the compute program for ``plan`` under mocks (``mocks`` answering, else
    :data:`PLACEHOLDERS`); a plan without a cloud network (another target's) declares nothing."""
    if plan.network is None:
        return OfflinePlan(plan=plan, resources=(), outputs=MappingProxyType({}))
    need("pulumi")  # a missing SDK names the aws extra, before the engine asks for it
    program = need("stacks.aws.program")

    def programs(earlier: Earlier) -> dict[str, Program]:
        return program.layer_programs(
            plan, certs=offline_bundle(plan.stack), operator_cidrs=(OPERATOR_PLACEHOLDER,),  # for ssh_from: auto
            public_key_openssh=offline_public_key(plan.stack), network_outputs=lambda: earlier("network"))

    return offline.declare(plan, Project(PROJECT, plan.stack, LAYERS), programs,
                           answers=mocks if mocks is not None else PLACEHOLDERS)
