"""The offline plan as Terraform plan JSON, for policy scanners (checkov, Trivy, OPA/conftest).

pulumi-aws is bridged from terraform-provider-aws, so every resource fogiac declares has a
Terraform type and every input a Terraform attribute: ``aws:ec2/vpc:Vpc`` is ``aws_vpc`` and
``cidrBlock`` is ``cidr_block``. Nested objects become lists of objects (as Terraform's JSON has
blocks), maps (tags) stay maps. A value the offline plan shows as another resource's placeholder
(``<motion-dev-vpc.id>``) is unknown until apply, as in ``terraform show -json``: it is left out of
the planned values and named as a reference in ``configuration``, so a scanner sees which security
group guards which instance and which VPC a flow log watches.

Scanners read ``planned_values``, ``resource_changes`` and ``configuration``; the ``fogiac`` key is
ignored by them and carries the checks fogiac fails by design (:data:`BY_DESIGN`), each with its
reason, for the CI gate to pass to the scanner (``.ci/policy.sh``: ``checkov --skip-check``).
"""

from __future__ import annotations

import copy
import re
from collections.abc import Mapping
from typing import Any

from fogiac import __version__
from fogiac.errors import PlanError

FORMAT_VERSION = "1.2"  # Terraform's plan JSON format (terraform show -json, 1.5 and later)
TERRAFORM_VERSION = "1.9.0"  # the Terraform the document reads as; no Terraform runs
PROVIDER = "registry.terraform.io/hashicorp/aws"

# Pulumi type token -> Terraform resource type (pulumi-aws's bridge mapping, for what stacks/ declares).
TYPES: dict[str, str] = {
    "aws:ec2/vpc:Vpc": "aws_vpc",
    "aws:ec2/defaultSecurityGroup:DefaultSecurityGroup": "aws_default_security_group",
    "aws:ec2/internetGateway:InternetGateway": "aws_internet_gateway",
    "aws:ec2/subnet:Subnet": "aws_subnet",
    "aws:ec2/routeTable:RouteTable": "aws_route_table",
    "aws:ec2/routeTableAssociation:RouteTableAssociation": "aws_route_table_association",
    "aws:ec2/securityGroup:SecurityGroup": "aws_security_group",
    "aws:vpc/securityGroupIngressRule:SecurityGroupIngressRule": "aws_vpc_security_group_ingress_rule",
    "aws:vpc/securityGroupEgressRule:SecurityGroupEgressRule": "aws_vpc_security_group_egress_rule",
    "aws:ec2/flowLog:FlowLog": "aws_flow_log",
    "aws:cloudwatch/logGroup:LogGroup": "aws_cloudwatch_log_group",
    "aws:iam/role:Role": "aws_iam_role",
    "aws:iam/rolePolicy:RolePolicy": "aws_iam_role_policy",
    "aws:acm/certificate:Certificate": "aws_acm_certificate",
    "aws:ec2clientvpn/endpoint:Endpoint": "aws_ec2_client_vpn_endpoint",
    "aws:ec2clientvpn/networkAssociation:NetworkAssociation": "aws_ec2_client_vpn_network_association",
    "aws:ec2clientvpn/authorizationRule:AuthorizationRule": "aws_ec2_client_vpn_authorization_rule",
    "aws:ec2/keyPair:KeyPair": "aws_key_pair",
    "aws:ec2/instance:Instance": "aws_instance",
}
# Where Pulumi's name is not the snake_case of Terraform's (Pulumi pluralises repeated blocks).
RENAMED: dict[tuple[str, str], str] = {("aws_route_table", "routes"): "route"}
MAPS = frozenset({"tags", "volume_tags", "tags_all"})  # map attributes: keys kept as written

# Checks fogiac fails on purpose, with the one-sentence reason docs/guides/pull-requests.md gives.
# ``when``: a plan-level condition under which the check is declared ("always", or "no flow logs").
BY_DESIGN: tuple[tuple[str, str, str], ...] = (
    ("CKV_AWS_88", "always",
     "Hosts have public addresses so the operator can SSH to them and, in proxy mode, the edge can reach the relay; "
     "ingress is only from ssh_from and inside the VPC."),
    ("CKV2_AWS_41", "always",
     "Hosts get no IAM instance profile on purpose: nothing on a host needs AWS credentials, so none can leak."),
    ("CKV_AWS_126", "always",
     "Detailed (1-minute) monitoring is billed per instance and fogiac's autostop watchdog runs on the host, "
     "not on CloudWatch metrics."),
    ("CKV_AWS_158", "always",
     "Log groups use CloudWatch Logs' own encryption; a customer KMS key would outlive the stack that down removes."),
    ("CKV2_AWS_11", "no flow logs",
     "VPC flow logs are opt-in (network.flow_logs: true) because CloudWatch bills their ingestion per GB."),
)

_PLACEHOLDER = re.compile(r"^<([^<>]+)\.([A-Za-z]+)>$")  # <logical-name.attr>: another resource's output


def snake(name: str) -> str:
    return re.sub(r"(?<=[a-z0-9])([A-Z])", r"_\1", name).lower()


def tf_name(logical: str) -> str:
    """A Terraform resource name for a Pulumi logical name (letters, digits, ``_`` and ``-``)."""
    return re.sub(r"[^A-Za-z0-9_-]", "_", logical)


def tf_type(token: str) -> str:
    try:
        return TYPES[token]
    except KeyError:
        raise PlanError(f"no Terraform type known for {token!r}; add it to fogiac.targets.aws.tfplan.TYPES") from None


def _refs(value: Any, addresses: Mapping[str, str]) -> list[str]:
    """The addresses ``value`` (a placeholder, or a list of them) points at; [] when it is a constant."""
    items = value if isinstance(value, list) else [value]
    out: list[str] = []
    for item in items:
        match = _PLACEHOLDER.match(item) if isinstance(item, str) else None
        if match and match.group(1) in addresses:
            address = addresses[match.group(1)]
            out += [f"{address}.{snake(match.group(2))}", address]
    return out


def _convert(tf: str, inputs: Mapping[str, Any], addresses: Mapping[str, str]) -> tuple[dict, dict, dict]:
    """(values, after_unknown, expressions) for one resource's (or nested block's) inputs."""
    values: dict[str, Any] = {}
    unknown: dict[str, Any] = {}
    expressions: dict[str, Any] = {}
    for key, value in inputs.items():
        attr = RENAMED.get((tf, key), snake(key))
        if attr in MAPS and isinstance(value, Mapping):
            values[attr] = dict(value)
            expressions[attr] = {"constant_value": dict(value)}
            continue
        blocks = [value] if isinstance(value, Mapping) else value
        if isinstance(blocks, list) and blocks and all(isinstance(b, Mapping) for b in blocks):
            converted = [_convert(tf, b, addresses) for b in blocks]
            values[attr] = [c[0] for c in converted]
            if any(c[1] for c in converted):
                unknown[attr] = [c[1] for c in converted]
            expressions[attr] = [c[2] for c in converted]
            continue
        refs = _refs(value, addresses)
        if refs:
            unknown[attr] = [True] * len(value) if isinstance(value, list) else True
            expressions[attr] = {"references": refs}
        else:
            values[attr] = value
            expressions[attr] = {"constant_value": value}
    return values, unknown, expressions


def _before_inputs(row: Mapping[str, Any]) -> dict[str, Any]:
    """An updated or replaced resource's inputs before: its inputs with each changed path's old value."""
    inputs = copy.deepcopy(dict(row["inputs"]))
    for path, old in (row.get("before") or {}).items():
        *parents, leaf = str(path).split(".")
        here = inputs
        for key in parents:
            here = here.setdefault(key, {}) if isinstance(here.get(key, {}), dict) else {}
        if old is None:
            here.pop(leaf, None)
        else:
            here[leaf] = old
    return inputs


def _actions(action: str) -> list[str]:
    return {"replace": ["delete", "create"], "no-op": ["no-op"]}.get(action, [action])


def by_design(doc: Mapping[str, Any]) -> list[dict[str, str]]:
    """The checks this plan fails by design, each with its reason."""
    flow_logs = any(r["type"] == "aws:ec2/flowLog:FlowLog" for r in doc["resources"])
    return [{"check": check, "reason": reason} for check, when, reason in BY_DESIGN
            if when == "always" or (when == "no flow logs" and not flow_logs)]


def export(doc: Mapping[str, Any]) -> dict[str, Any]:
    """The plan document ``doc`` (``fogiac plan --json``) as Terraform plan JSON."""
    rows = list(doc["resources"])
    addresses = {r["name"]: f"{tf_type(r['type'])}.{tf_name(r['name'])}" for r in rows}
    planned: list[dict[str, Any]] = []
    changes: list[dict[str, Any]] = []
    configured: list[dict[str, Any]] = []
    for r in rows:
        tf, name = tf_type(r["type"]), tf_name(r["name"])
        address = addresses[r["name"]]
        values, unknown, expressions = _convert(tf, r["inputs"], addresses)
        head = {"address": address, "mode": "managed", "type": tf, "name": name}
        action = r.get("action", "create")
        before = _convert(tf, _before_inputs(r), addresses)[0] if action in ("update", "replace") else values
        if action != "delete":
            planned.append({**head, "provider_name": PROVIDER, "schema_version": 0, "values": values,
                            "sensitive_values": {}})
        changes.append({**head, "provider_name": PROVIDER, "change": {
            "actions": _actions(action),
            "before": None if action == "create" else before,
            "after": None if action == "delete" else values,
            "after_unknown": unknown, "before_sensitive": False, "after_sensitive": {}}})
        configured.append({**head, "provider_config_key": "aws", "expressions": expressions, "schema_version": 0})
    return {
        "format_version": FORMAT_VERSION,
        "terraform_version": TERRAFORM_VERSION,
        "planned_values": {"root_module": {"resources": planned}},
        "resource_changes": changes,
        "configuration": {
            "provider_config": {"aws": {"name": "aws", "full_name": PROVIDER,
                                        "expressions": {"region": {"constant_value": doc["region"]}}}},
            "root_module": {"resources": configured},
        },
        "fogiac": {"version": __version__, "stack": doc["stack"], "plan_digest": doc["plan_digest"],
                   "by_design": by_design(doc)},
    }
