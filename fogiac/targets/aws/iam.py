"""The IAM permissions fogiac needs on AWS, shipped as a policy document, and ``doctor``'s check of them.

``data/iam-policy.json`` is the policy to attach to the user or role fogiac runs as
(``python -m fogiac.targets.aws.iam`` prints it). It is least privilege against the caller turning it into
more: a role may be created (and given an inline policy) only with the account's ``fogiac-boundary``
permissions boundary on it (``data/iam-boundary.json``, ``--boundary`` prints it; writing flow logs is all
it allows) and passed only to VPC flow logs; whatever deletes, stops, modifies or re-tags needs the
resource to carry ``fogiac:stack`` already, and that tag is given only at creation (``ec2:CreateAction``),
so nothing fogiac did not create can be touched. It allows two kinds of actions:

- the AWS API calls fogiac makes itself through boto3 (preflight, status, refresh, sweep, quotas,
  waking stopped instances, reading host keys from the console); a test scans this package for
  every botocore operation it names and checks that the document allows each one;
- the calls the AWS provider makes to create, read, update and delete each resource type the
  stack programs declare (:data:`RESOURCE_ACTIONS`); a test checks that every type an example
  plan declares has an entry here and that the document allows its actions. The provider's exact
  calls are AWS's and the provider's: this list is checked against them only in real use.

:func:`doctor_check` asks IAM's policy simulator whether the caller may make the actions a plan
needs (its resource types' and fogiac's own) and names those it may not; without credentials it
says which document to attach and checks nothing (offline).
"""

from __future__ import annotations

import json
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from fogiac.errors import CloudError
from fogiac.extras import need
from fogiac.plan.model import Plan
from fogiac.targets.aws import api
from fogiac.targets.base import Check

POLICY_FILE = Path(__file__).parent / "data" / "iam-policy.json"
BOUNDARY_FILE = Path(__file__).parent / "data" / "iam-boundary.json"  # the account's ``fogiac-boundary`` policy
BOUNDARY = "arn:aws:iam::{account}:policy/fogiac-boundary"  # as stacks/aws/network.py sets it on the roles it makes

# the document's statements of fogiac's own calls
OWN_STATEMENTS = ("FogiacReads", "FogiacChangesOnlyWhatItTagged", "FogiacReadsItsRoles", "FogiacSweepsItsRoles",
                  "FogiacSweepsItsRolesPolicies", "Doctor")  # (DoctorReadsTheBoundary: doctor's own read, not a plan's)
ROLE_TYPES = ("aws:iam/role:Role",)  # the declared resources that are roles, each made with the boundary on it


def own_request(account: str) -> dict[str, list[str]]:
    """The condition keys of the requests fogiac itself makes (what the policy's conditions ask of them): a
    resource tagged ``fogiac:stack``, tags given at creation, a role created with the boundary and passed
    only to flow logs. ``doctor`` hands these to IAM's simulator, which otherwise evaluates every condition
    as unmet; the tests evaluate the policy under the same keys."""
    return {"aws:ResourceTag/fogiac:stack": ["a-stack"], "aws:RequestTag/fogiac:stack": ["a-stack"],
            "aws:TagKeys": ["Name"], "ec2:CreateAction": ["RunInstances"],
            "iam:PermissionsBoundary": [BOUNDARY.format(account=account)],
            "iam:PassedToService": ["vpc-flow-logs.amazonaws.com"]}
_TAGS = ("ec2:CreateTags", "ec2:DeleteTags", "ec2:DescribeTags")
_SG_RULES = ("ec2:DescribeSecurityGroupRules", "ec2:ModifySecurityGroupRules", "ec2:DescribeSecurityGroups")

# What the AWS provider calls for each resource type the stack programs declare (create, read, update, delete).
RESOURCE_ACTIONS: Mapping[str, tuple[str, ...]] = {
    "aws:ec2/vpc:Vpc": ("ec2:CreateVpc", "ec2:DeleteVpc", "ec2:DescribeVpcs", "ec2:DescribeVpcAttribute",
                        "ec2:ModifyVpcAttribute", "ec2:DescribeNetworkAcls", "ec2:DescribeRouteTables",
                        "ec2:DescribeSecurityGroups", *_TAGS),
    "aws:ec2/subnet:Subnet": ("ec2:CreateSubnet", "ec2:DeleteSubnet", "ec2:DescribeSubnets",
                              "ec2:ModifySubnetAttribute", "ec2:DescribeNetworkInterfaces", *_TAGS),
    "aws:ec2/internetGateway:InternetGateway": ("ec2:CreateInternetGateway", "ec2:AttachInternetGateway",
                                                "ec2:DetachInternetGateway", "ec2:DeleteInternetGateway",
                                                "ec2:DescribeInternetGateways", *_TAGS),
    "aws:ec2/routeTable:RouteTable": ("ec2:CreateRouteTable", "ec2:DeleteRouteTable", "ec2:DescribeRouteTables",
                                      "ec2:CreateRoute", "ec2:DeleteRoute", "ec2:ReplaceRoute", *_TAGS),
    "aws:ec2/routeTableAssociation:RouteTableAssociation": ("ec2:AssociateRouteTable", "ec2:DisassociateRouteTable",
                                                            "ec2:ReplaceRouteTableAssociation",
                                                            "ec2:DescribeRouteTables"),
    "aws:ec2/securityGroup:SecurityGroup": ("ec2:CreateSecurityGroup", "ec2:DeleteSecurityGroup",
                                            "ec2:AuthorizeSecurityGroupIngress", "ec2:AuthorizeSecurityGroupEgress",
                                            "ec2:RevokeSecurityGroupIngress", "ec2:RevokeSecurityGroupEgress",
                                            "ec2:DescribeNetworkInterfaces", *_SG_RULES, *_TAGS),
    "aws:ec2/defaultSecurityGroup:DefaultSecurityGroup": ("ec2:AuthorizeSecurityGroupIngress",
                                                          "ec2:AuthorizeSecurityGroupEgress",
                                                          "ec2:RevokeSecurityGroupIngress",
                                                          "ec2:RevokeSecurityGroupEgress", *_SG_RULES, *_TAGS),
    "aws:vpc/securityGroupIngressRule:SecurityGroupIngressRule": ("ec2:AuthorizeSecurityGroupIngress",
                                                                  "ec2:RevokeSecurityGroupIngress", *_SG_RULES,
                                                                  *_TAGS),
    "aws:vpc/securityGroupEgressRule:SecurityGroupEgressRule": ("ec2:AuthorizeSecurityGroupEgress",
                                                                "ec2:RevokeSecurityGroupEgress", *_SG_RULES, *_TAGS),
    "aws:ec2/keyPair:KeyPair": ("ec2:ImportKeyPair", "ec2:DeleteKeyPair", "ec2:DescribeKeyPairs", *_TAGS),
    "aws:ec2/instance:Instance": ("ec2:RunInstances", "ec2:TerminateInstances", "ec2:StartInstances",
                                  "ec2:StopInstances", "ec2:DescribeInstances", "ec2:DescribeInstanceAttribute",
                                  "ec2:ModifyInstanceAttribute", "ec2:ModifyInstanceMetadataOptions",
                                  "ec2:DescribeInstanceTypes", "ec2:DescribeInstanceCreditSpecifications",
                                  "ec2:DescribeImages", "ec2:DescribeVolumes", "ec2:DescribeNetworkInterfaces",
                                  "ec2:GetConsoleOutput", *_TAGS),
    "aws:ec2/flowLog:FlowLog": ("ec2:CreateFlowLogs", "ec2:DeleteFlowLogs", "ec2:DescribeFlowLogs", "iam:PassRole",
                                *_TAGS),
    "aws:cloudwatch/logGroup:LogGroup": ("logs:CreateLogGroup", "logs:DeleteLogGroup", "logs:DescribeLogGroups",
                                         "logs:PutRetentionPolicy", "logs:DeleteRetentionPolicy",
                                         "logs:TagResource", "logs:UntagResource", "logs:ListTagsForResource",
                                         "logs:TagLogGroup", "logs:ListTagsLogGroup"),
    "aws:acm/certificate:Certificate": ("acm:ImportCertificate", "acm:DeleteCertificate", "acm:DescribeCertificate",
                                        "acm:GetCertificate", "acm:ListTagsForCertificate",
                                        "acm:AddTagsToCertificate", "acm:RemoveTagsFromCertificate"),
    "aws:ec2clientvpn/endpoint:Endpoint": ("ec2:CreateClientVpnEndpoint", "ec2:DeleteClientVpnEndpoint",
                                           "ec2:DescribeClientVpnEndpoints", "ec2:ModifyClientVpnEndpoint",
                                           "ec2:ApplySecurityGroupsToClientVpnTargetNetwork",
                                           "acm:DescribeCertificate", "logs:DescribeLogStreams",
                                           "logs:CreateLogStream", *_TAGS),
    "aws:ec2clientvpn/networkAssociation:NetworkAssociation": ("ec2:AssociateClientVpnTargetNetwork",
                                                               "ec2:DisassociateClientVpnTargetNetwork",
                                                               "ec2:DescribeClientVpnTargetNetworks"),
    "aws:ec2clientvpn/authorizationRule:AuthorizationRule": ("ec2:AuthorizeClientVpnIngress",
                                                             "ec2:RevokeClientVpnIngress",
                                                             "ec2:DescribeClientVpnAuthorizationRules"),
    "aws:iam/role:Role": ("iam:CreateRole", "iam:DeleteRole", "iam:GetRole", "iam:TagRole", "iam:UntagRole",
                          "iam:UpdateAssumeRolePolicy", "iam:ListRolePolicies", "iam:ListAttachedRolePolicies",
                          "iam:ListInstanceProfilesForRole"),
    "aws:iam/rolePolicy:RolePolicy": ("iam:PutRolePolicy", "iam:GetRolePolicy", "iam:DeleteRolePolicy"),
}


def policy() -> dict[str, Any]:
    """The shipped policy document."""
    return dict(json.loads(POLICY_FILE.read_text()))


def allowed() -> frozenset[str]:
    """Every action the shipped document allows."""
    return frozenset(action for statement in policy()["Statement"] if statement["Effect"] == "Allow"
                     for action in ([statement["Action"]] if isinstance(statement["Action"], str)
                                    else statement["Action"]))


def own_actions() -> frozenset[str]:
    """The actions of fogiac's own boto3 calls (and the simulator doctor asks)."""
    return frozenset(action for statement in policy()["Statement"]
                     if statement["Sid"] in OWN_STATEMENTS for action in statement["Action"])


def needed(resource_types: Iterable[str]) -> frozenset[str]:
    """What a plan whose stacks declare ``resource_types`` needs: their actions and fogiac's own calls."""
    return own_actions() | frozenset(a for t in resource_types for a in RESOURCE_ACTIONS.get(t, ()))


def _principal(arn: str) -> str:
    """The ARN the simulator takes: an assumed role's role, else the caller itself."""
    parts = arn.split(":")
    if len(parts) == 6 and parts[2] == "sts" and parts[5].startswith("assumed-role/"):
        role = parts[5].split("/")[1]
        return f"arn:aws:iam::{parts[4]}:role/{role}"
    return arn


def denied(actions: Iterable[str], *, region: str, sts: Any = None, iam: Any = None) -> list[str]:
    """The actions the caller may not make on fogiac's own requests (:func:`own_request`), by IAM's policy
    simulator (sorted)."""
    sts = sts or api.client("sts", region=region)
    iam = iam or api.client("iam", region=region)
    identity = api._call(sts.get_caller_identity)
    caller = _principal(str(identity["Arn"]))
    context = [{"ContextKeyName": key, "ContextKeyValues": values,
                "ContextKeyType": "stringList" if len(values) > 1 or key == "aws:TagKeys" else "string"}
               for key, values in own_request(str(identity["Account"])).items()]
    wanted = sorted(actions)
    refused: list[str] = []
    for start in range(0, len(wanted), 100):
        result = api._call(iam.simulate_principal_policy, PolicySourceArn=caller,
                           ActionNames=wanted[start:start + 100], ContextEntries=context)
        refused += [r["EvalActionName"] for r in result["EvaluationResults"] if r["EvalDecision"] != "allowed"]
    return sorted(refused)


def doctor_check(plan: Plan, resource_types: Iterable[str], *, sts: Any = None, iam: Any = None) -> Check:
    """``fogiac doctor``'s line about permissions; offline and "not checked" when there are no credentials."""
    actions = needed(resource_types)
    where = "attach the policy fogiac ships (`python -m fogiac.targets.aws.iam` prints it)"
    errors = need("botocore.exceptions")
    try:
        refused = denied(actions, region=plan.region, sts=sts, iam=iam)
    except CloudError as err:  # no or rejected credentials, AWS unreachable: say what is needed, check nothing
        return Check("IAM policy", True, f"not checked ({err}); this plan needs {len(actions)} actions: {where}")
    except errors.ClientError as err:
        code = api.error_code(err)
        return Check("IAM policy", True, f"not checked (IAM's policy simulator answered {code}; checking needs "
                                         f"iam:SimulatePrincipalPolicy); {where}")
    if refused:
        shown = ", ".join(refused[:8]) + (f" and {len(refused) - 8} more" if len(refused) > 8 else "")
        return Check("IAM policy", False, f"{len(refused)} of the {len(actions)} actions this plan needs are "
                                          f"denied: {shown}; {where}")
    return Check("IAM policy", True, f"the caller may make all {len(actions)} actions this plan needs")


def boundary_check(plan: Plan, resource_types: Iterable[str], *, sts: Any = None, iam: Any = None) -> Check:
    """``fogiac doctor``'s line about the account's ``fogiac-boundary`` policy: the shipped policy lets fogiac
    create a role only with it on, so a plan that makes a role (``flow_logs: true``) fails at ``up`` without
    it, after the network's other resources were made. A plan that makes no role needs none: said, not failed."""
    makes = sorted(set(resource_types) & set(ROLE_TYPES))
    create = "an administrator creates it once from `python -m fogiac.targets.aws.iam --boundary`"
    errors = need("botocore.exceptions")
    try:
        sts = sts or api.client("sts", region=plan.region)
        iam = iam or api.client("iam", region=plan.region)
        arn = BOUNDARY.format(account=api._call(sts.get_caller_identity)["Account"])
        api._call(iam.get_policy, PolicyArn=arn)
    except CloudError as err:  # no or rejected credentials, AWS unreachable: check nothing, say what is needed
        return Check("permissions boundary", True, f"not checked ({err}); roles fogiac makes carry the account's "
                                                   f"fogiac-boundary policy: {create}")
    except errors.ClientError as err:
        code = api.error_code(err)
        if code != "NoSuchEntity":
            return Check("permissions boundary", True, f"not checked (IAM answered {code}; checking needs "
                                                       "iam:GetPolicy on policy/fogiac-boundary)")
        if makes:
            return Check("permissions boundary", False, f"the account has no {arn}, which the role this plan makes "
                                                        f"(flow_logs: true) must carry, or up fails: {create}")
        return Check("permissions boundary", True, f"the account has no {arn}; this plan makes no role, so it "
                                                   f"needs none (flow_logs: true would: {create})")
    return Check("permissions boundary", True, f"{arn} exists")


if __name__ == "__main__":  # pragma: no cover
    sys.stdout.write((BOUNDARY_FILE if sys.argv[1:] == ["--boundary"] else POLICY_FILE).read_text())
