"""The aws offline plan as Terraform plan JSON, for policy scanners (checkov, Trivy, OPA/conftest).

pulumi-aws is bridged from terraform-provider-aws, so every resource fogiac declares has a
Terraform type and every input a Terraform attribute: ``aws:ec2/vpc:Vpc`` is ``aws_vpc`` and
``cidrBlock`` is ``cidr_block``. This module names those types, the attributes whose names differ,
the map attributes and the checks fogiac fails by design on aws (:data:`BY_DESIGN`, each with its
reason); the shaping of the document is the engine's (:mod:`fogiac.pulumi_engine.terraform`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from fogiac.pulumi_engine import terraform

PROVIDER = "registry.terraform.io/hashicorp/aws"

# Pulumi type token -> Terraform resource type (pulumi-aws's bridge mapping, for what stacks/aws/ declares).
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


def by_design(doc: Mapping[str, Any]) -> list[dict[str, str]]:
    """The checks this plan fails by design, each with its reason."""
    flow_logs = any(r["type"] == "aws:ec2/flowLog:FlowLog" for r in doc["resources"])
    return [{"check": check, "reason": reason} for check, when, reason in BY_DESIGN
            if when == "always" or (when == "no flow logs" and not flow_logs)]


AWS = terraform.Provider(name="aws", source=PROVIDER, types=TYPES, types_home="fogiac.targets.aws.tfplan.TYPES",
                         renamed=RENAMED, maps=MAPS, by_design=by_design,
                         config=lambda doc: {"region": {"constant_value": doc["region"]}})
tf_type = AWS.tf_type


def export(doc: Mapping[str, Any]) -> dict[str, Any]:
    """The plan document ``doc`` (``fogiac plan --json``) as Terraform plan JSON (the aws target's exporter)."""
    return terraform.export(doc, AWS)
