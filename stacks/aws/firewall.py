"""Firewall: the plan's security groups, one rule resource per rule and CIDR.

Rules come only from the compiled plan; this module adds nothing. The operator placeholder
in ``ssh_from: auto`` becomes each of the operator's real CIDRs, and the result is checked once
more here, at the last point before AWS: no ingress from 0.0.0.0/0 or ::/0, ever.
"""

from __future__ import annotations

import ipaddress
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import TypedDict

import pulumi
import pulumi_aws as aws

from fogiac.errors import PlanError
from fogiac.plan.model import OPERATOR, OPERATOR_PLACEHOLDER, Rule, SecurityGroup, check_ingress
from stacks.aws.tags import tagged


@dataclass(frozen=True)
class FirewallArgs:
    vpc_id: pulumi.Input[str]
    groups: tuple[SecurityGroup, ...]
    operator_cidrs: tuple[str, ...]
    tags: Mapping[str, str]


def expand(rules: tuple[Rule, ...], operator_cidrs: tuple[str, ...]) -> tuple[Rule, ...]:
    """``rules`` with the OPERATOR placeholder replaced by each operator CIDR, duplicates dropped.

    AWS rejects a duplicate rule, and one can arise when ``ssh_from`` repeats a VPC range.
    """
    out: list[Rule] = []
    seen: set[tuple[str, int, int, str]] = set()
    for rule in rules:
        if rule.cidr == OPERATOR and not operator_cidrs:
            raise PlanError(f"rule {rule.description!r} needs the operator's address but none was given")
        for cidr in operator_cidrs if rule.cidr == OPERATOR else (rule.cidr,):
            key = (rule.protocol, rule.from_port, rule.to_port, cidr)
            if key not in seen:
                seen.add(key)
                out.append(replace(rule, cidr=cidr))
    return tuple(out)


def rule_name(prefix: str, rule: Rule) -> str:
    """A stable logical name from the rule's content, so reordering rules replaces nothing."""
    ports = "all" if rule.protocol == "-1" else str(rule.from_port)
    if rule.protocol != "-1" and rule.to_port != rule.from_port:
        ports += f"-{rule.to_port}"
    proto = "any" if rule.protocol == "-1" else rule.protocol
    cidr = rule.cidr.replace("/", "-").replace("<", "").replace(">", "")
    return f"{prefix}-{proto}-{ports}-{cidr}"


class _RuleArgs(TypedDict, total=False):
    """The keyword arguments SecurityGroupIngressRule and SecurityGroupEgressRule share, typed
    so the type checker checks them against pulumi_aws's signatures."""

    security_group_id: pulumi.Input[str]
    ip_protocol: str
    description: str
    tags: dict[str, str]
    cidr_ipv4: str
    cidr_ipv6: str
    from_port: int
    to_port: int


def _rule_args(rule: Rule, group_id: pulumi.Input[str], tags: Mapping[str, str]) -> _RuleArgs:
    args: _RuleArgs = {
        "security_group_id": group_id,
        "ip_protocol": rule.protocol,
        "description": rule.description,
        "tags": dict(tags),
    }
    network = None if rule.cidr == OPERATOR_PLACEHOLDER else ipaddress.ip_network(rule.cidr, strict=False)
    if network is not None and network.version == 6:
        args["cidr_ipv6"] = rule.cidr
    else:
        args["cidr_ipv4"] = rule.cidr
    if rule.protocol != "-1":  # AWS takes no ports for "all protocols"
        args["from_port"] = rule.from_port
        args["to_port"] = rule.to_port
    return args


class Firewall(pulumi.ComponentResource):
    """One security group per plan group; rules are separate resources (no inline rules)."""

    groups: dict[str, aws.ec2.SecurityGroup]

    def __init__(self, name: str, args: FirewallArgs, opts: pulumi.ResourceOptions | None = None) -> None:
        super().__init__("fogiac:aws:Firewall", name, None, opts)
        child = pulumi.ResourceOptions(parent=self)
        self.groups = {}
        self.rules: list[pulumi.CustomResource] = []
        for group in args.groups:
            ingress = expand(group.ingress, args.operator_cidrs)
            egress = expand(group.egress, args.operator_cidrs)
            check_ingress(group.name, ingress)
            sg = aws.ec2.SecurityGroup(
                f"{name}-sg-{group.name}",
                name=f"fogiac-{name}-{group.name}",  # AWS refuses names starting "sg-"
                description=group.description,
                vpc_id=args.vpc_id,
                tags=tagged(args.tags, f"{name}-{group.name}"),
                opts=child,
            )
            self.groups[group.name] = sg
            for rule in ingress:
                self.rules.append(
                    aws.vpc.SecurityGroupIngressRule(
                        rule_name(f"{name}-{group.name}-in", rule), **_rule_args(rule, sg.id, args.tags), opts=child
                    )
                )
            for rule in egress:
                self.rules.append(
                    aws.vpc.SecurityGroupEgressRule(
                        rule_name(f"{name}-{group.name}-out", rule), **_rule_args(rule, sg.id, args.tags), opts=child
                    )
                )
        self.register_outputs({"security_group_ids": {key: sg.id for key, sg in self.groups.items()}})
