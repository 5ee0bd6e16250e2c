"""What AWS reports about a stack, and how it differs from the applied plan document (drift).

:func:`observe` asks EC2 (clients from :mod:`.api`) for the stack's instances and security
groups, found by the ``fogiac:stack`` tag, with every ingress rule of those groups, tagged or not:
a rule someone added in the console carries no tag. :func:`compare` is pure: the applied
document and the observation in, :class:`~fogiac.plan.drift.Drift` rows out.

Matching: an instance by its ``fogiac:host`` tag (a replica) or ``fogiac:node`` tag (the host), a
security group by its name, an ingress rule by protocol, ports and source. The applied document is
the offline plan, so the operator's address is a placeholder there (``<operator>/32``) and the AMI
a query: a rule with a placeholder source matches the addresses ``ssh_from`` resolved to at the
apply (recorded in outputs.json), and the AMI is compared only where the document names one. A
stopped instance is not drift (autostop stops them).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from typing import Any

from fogiac.plan.drift import Drift
from fogiac.targets.aws import api

INSTANCE = "aws:ec2/instance:Instance"
GROUP = "aws:ec2/securityGroup:SecurityGroup"
DEFAULT_GROUP = "aws:ec2/defaultSecurityGroup:DefaultSecurityGroup"  # adopted with no rules: any rule is drift
INGRESS = "aws:vpc/securityGroupIngressRule:SecurityGroupIngressRule"
GONE = {"shutting-down", "terminated"}


def observe(stack: str, *, region: str, ec2: Any = None) -> dict[str, Any]:
    """The stack's instances (type, state, AMI) and security groups (every ingress rule), as JSON."""
    ec2 = ec2 or api.client("ec2", region=region)
    instances = [
        {"instance_id": i["InstanceId"], "host": api.host_of(api.tags_of(i)), "type": i["InstanceType"],
         "state": i["State"]["Name"], "ami": i.get("ImageId", "")}
        for r in api.paginate(ec2, "describe_instances", "Reservations", Filters=api.tag_filter(stack))
        for i in r["Instances"]]
    groups = api.paginate(ec2, "describe_security_groups", "SecurityGroups", Filters=api.tag_filter(stack))
    rules: list[Any] = []
    if groups:
        rules = api.paginate(ec2, "describe_security_group_rules", "SecurityGroupRules",
                             Filters=[{"Name": "group-id", "Values": [g["GroupId"] for g in groups]}])
    return {
        "instances": sorted(instances, key=lambda i: (i["host"], i["instance_id"])),
        "security_groups": [
            {"group_id": g["GroupId"], "name": g["GroupName"], "ingress": [
                {"rule_id": r["SecurityGroupRuleId"], "protocol": str(r["IpProtocol"]),
                 "from": r.get("FromPort", -1), "to": r.get("ToPort", -1),
                 "source": r.get("CidrIpv4") or r.get("CidrIpv6") or r.get("PrefixListId") or
                 (r.get("ReferencedGroupInfo") or {}).get("GroupId", ""), "description": r.get("Description", "")}
                for r in rules if r["GroupId"] == g["GroupId"] and not r.get("IsEgress")]}
            for g in sorted(groups, key=lambda g: g["GroupName"])],
    }


def compare(applied: Mapping[str, Any], observed: Mapping[str, Any], *,
            operator_cidrs: Collection[str] | None = None) -> list[Drift]:
    """Each applied instance, security group and ingress rule whose cloud state differs, and rules added.

    ``operator_cidrs``: what ``ssh_from`` resolved to at the apply (outputs.json); None for a stack
    applied before fogiac recorded it, where the operator's rules match by description instead.
    """
    rows = applied.get("resources", [])
    return _instances(rows, observed["instances"]) + _groups(rows, observed["security_groups"], operator_cidrs)


def _instances(rows: list[Mapping[str, Any]], seen: list[Mapping[str, Any]]) -> list[Drift]:
    out = []
    for row in (r for r in rows if r["type"] == INSTANCE):
        inputs = row["inputs"]
        host = api.host_of(inputs.get("tags") or {})
        live = [i for i in seen if i["host"] == host and i["state"] not in GONE]
        if not live:
            out.append(Drift(row["stack"], INSTANCE, row["name"], "deleted"))
            continue
        actual = live[0]
        changes = [("instanceType", inputs.get("instanceType"), actual["type"])]
        if str(inputs.get("ami", "")).startswith("ami-"):  # offline documents hold the AMI query, not an id
            changes.append(("ami", inputs["ami"], actual["ami"]))
        changed = tuple(c for c in changes if c[1] != c[2])
        if changed:
            out.append(Drift(row["stack"], INSTANCE, row["name"], "changed", changed))
    return out


def _matches(rule: Mapping[str, Any], inputs: Mapping[str, Any], operator_cidrs: Collection[str] | None) -> bool:
    protocol = str(inputs.get("ipProtocol"))
    if rule["protocol"] != protocol:
        return False
    if protocol != "-1" and (rule["from"], rule["to"]) != (inputs.get("fromPort"), inputs.get("toPort")):
        return False
    source = str(inputs.get("cidrIpv4") or inputs.get("cidrIpv6") or "")
    if "<" in source:  # the operator's address, filled in at apply time
        if operator_cidrs is None:
            return bool(rule["description"] == inputs.get("description"))
        return rule["source"] in operator_cidrs
    return bool(rule["source"] == source)


def _rule_text(rule: Mapping[str, Any], group: str) -> str:
    ports = "all ports" if rule["protocol"] == "-1" else (
        f"port {rule['from']}" if rule["from"] == rule["to"] else f"ports {rule['from']}-{rule['to']}")
    protocol = "all protocols" if rule["protocol"] == "-1" else rule["protocol"]
    said = f" ({rule['description']})" if rule["description"] else ""
    return f"{group} {protocol} {ports} from {rule['source']}{said}"


def _groups(rows: list[Mapping[str, Any]], seen: list[Mapping[str, Any]],
            operator_cidrs: Collection[str] | None) -> list[Drift]:
    out = []
    by_name = {g["name"]: g for g in seen}
    for row in (r for r in rows if r["type"] == GROUP):
        group = by_name.get(row["inputs"].get("name"))
        if group is None:
            out.append(Drift(row["stack"], GROUP, row["name"], "deleted"))
            continue
        unmatched = list(group["ingress"])
        for rule_row in (r for r in rows if r["type"] == INGRESS and r["inputs"].get("securityGroupId") ==
                         f"<{row['name']}.id>"):
            found = next((r for r in unmatched if _matches(r, rule_row["inputs"], operator_cidrs)), None)
            if found is None:
                out.append(Drift(rule_row["stack"], INGRESS, rule_row["name"], "deleted"))
            else:
                unmatched.remove(found)
        out += [Drift(row["stack"], INGRESS, r["rule_id"], "added", detail=_rule_text(r, group["name"]))
                for r in unmatched]
    default = by_name.get("default")
    for row in (r for r in rows if r["type"] == DEFAULT_GROUP):
        out += [Drift(row["stack"], INGRESS, r["rule_id"], "added", detail=_rule_text(r, "default"))
                for r in (default or {}).get("ingress", [])]
    return out
