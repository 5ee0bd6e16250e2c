"""Security groups: exactly the compiled rules, never open to the world, SSH only from ssh_from."""

from __future__ import annotations

import ipaddress

import pytest

from fogiac.errors import PlanError
from fogiac.plan.model import OPERATOR, OPERATOR_PLACEHOLDER, Rule, check_ingress
from fogiac.targets.aws.offline import OfflinePlan
from stacks.aws.firewall import expand, rule_name

INGRESS = "aws:vpc/securityGroupIngressRule:SecurityGroupIngressRule"
EGRESS = "aws:vpc/securityGroupEgressRule:SecurityGroupEgressRule"


def declared_rules(plan: OfflinePlan, type_: str) -> set[tuple[str, str, int | None, int | None, str, str]]:
    groups = {f"<{plan.plan.stack}-sg-{g.name}.id>": g.name for g in plan.plan.security_groups}
    return {
        (
            groups[r.inputs["securityGroupId"]],
            r.inputs["ipProtocol"],
            r.inputs.get("fromPort"),
            r.inputs.get("toPort"),
            r.inputs.get("cidrIpv4") or r.inputs["cidrIpv6"],
            r.inputs["description"],
        )
        for r in plan.of_type(type_)
    }


def compiled_rules(plan: OfflinePlan, direction: str) -> set[tuple[str, str, int | None, int | None, str, str]]:
    out = set()
    for group in plan.plan.security_groups:
        for rule in expand(getattr(group, direction), (OPERATOR_PLACEHOLDER,)):
            ports = (None, None) if rule.protocol == "-1" else (rule.from_port, rule.to_port)
            out.add((group.name, rule.protocol, *ports, rule.cidr, rule.description))
    return out


@pytest.mark.parametrize("key", ["minimal", "proxy", "gpu"])
def test_rules_are_exactly_the_compiled_ones(offline: dict[str, OfflinePlan], key: str) -> None:
    plan = offline[key]
    assert declared_rules(plan, INGRESS) == compiled_rules(plan, "ingress")
    assert declared_rules(plan, EGRESS) == compiled_rules(plan, "egress")
    assert len(plan.of_type(INGRESS)) == len(compiled_rules(plan, "ingress"))


@pytest.mark.parametrize("key", ["minimal", "proxy", "gpu"])
def test_no_ingress_from_the_whole_internet(offline: dict[str, OfflinePlan], key: str) -> None:
    for r in offline[key].of_type(INGRESS):
        cidr = r.inputs.get("cidrIpv4") or r.inputs["cidrIpv6"]
        if cidr != OPERATOR_PLACEHOLDER:
            assert ipaddress.ip_network(cidr).prefixlen > 0, r.name


def test_ssh_only_from_ssh_from(offline: dict[str, OfflinePlan]) -> None:
    def ssh_sources(key: str) -> set[str]:
        return {
            r.inputs["cidrIpv4"]
            for r in offline[key].of_type(INGRESS)
            if r.inputs["fromPort"] <= 22 <= r.inputs["toPort"]
        }

    assert ssh_sources("minimal") == {OPERATOR_PLACEHOLDER}
    assert ssh_sources("proxy") == {"198.51.100.0/24", "203.0.113.7/32"}
    assert ssh_sources("gpu") == {"203.0.113.7/32"}


def test_proxy_mode_opens_the_relay_to_ssh_from_only(offline: dict[str, OfflinePlan]) -> None:
    relay = {r.inputs["cidrIpv4"] for r in offline["proxy"].of_type(INGRESS) if r.inputs["fromPort"] == 11411}
    assert relay == {"10.20.0.0/20", "198.51.100.0/24", "203.0.113.7/32"}


def test_vpn_mode_lets_vpn_clients_reach_ros(offline: dict[str, OfflinePlan]) -> None:
    master = {r.inputs["cidrIpv4"] for r in offline["minimal"].of_type(INGRESS) if r.inputs["fromPort"] == 11311}
    assert master == {"10.10.0.0/16", "10.200.0.0/22"}


def test_expand_replaces_the_operator_with_each_cidr_and_drops_duplicates() -> None:
    rules = (
        Rule("tcp", 22, 22, OPERATOR, "ssh"),
        Rule("tcp", 22, 22, "192.0.2.0/24", "ssh again"),
    )
    assert expand(rules, ("192.0.2.0/24", "198.51.100.9/32")) == (
        Rule("tcp", 22, 22, "192.0.2.0/24", "ssh"),
        Rule("tcp", 22, 22, "198.51.100.9/32", "ssh"),
    )


def test_expand_needs_an_operator_address() -> None:
    with pytest.raises(PlanError, match="^rule 'ssh' needs the operator's address but none was given$"):
        expand((Rule("tcp", 22, 22, OPERATOR, "ssh"),), ())


@pytest.mark.parametrize("cidr", ["0.0.0.0/0", "::/0"])
def test_world_ingress_is_refused(cidr: str) -> None:
    with pytest.raises(PlanError, match=rf"^security group 'hosts' would accept {cidr} on port 22$"):
        check_ingress("hosts", (Rule("tcp", 22, 22, cidr, "ssh"),))


def test_garbage_cidr_is_refused() -> None:
    with pytest.raises(PlanError, match=r"^security group 'hosts': 'nowhere' is not a CIDR$"):
        check_ingress("hosts", (Rule("tcp", 22, 22, "nowhere", "ssh"),))


def test_rule_names_come_from_content() -> None:
    assert rule_name("s-hosts-in", Rule("tcp", 22, 22, "10.0.0.0/8", "x")) == "s-hosts-in-tcp-22-10.0.0.0-8"
    assert rule_name("s-hosts-in", Rule("tcp", 1, 9, "10.0.0.0/8", "x")) == "s-hosts-in-tcp-1-9-10.0.0.0-8"
    assert rule_name("s-out", Rule("-1", 0, 0, "0.0.0.0/0", "x")) == "s-out-any-all-0.0.0.0-0"
