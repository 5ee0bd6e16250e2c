"""Issue 35 item 4: the shipped IAM policy cannot be turned into more than fogiac needs.

Evaluated by a static evaluator of the policy's statements (``tests/support/iam_eval.py``: Allow/Deny,
Action and Resource wildcards, policy variables, and the condition operators the policy uses), because
LocalStack's IAM has no working policy simulator (its ``SimulatePrincipalPolicy`` answers with an error,
as ``test_iam.py`` shows against a real LocalStack). Before the fix, every escalation and foreign deletion
below was allowed: ``CreateRole``, ``PutRolePolicy`` and ``PassRole`` had no condition and
``TerminateInstances``, ``Delete*``, ``CreateTags`` were granted on ``*``.
"""

from __future__ import annotations

import json
import re

import pytest

from fogiac.targets.aws import iam
from tests.support.iam_eval import decide

ACCOUNT = "123456789012"
BOUNDARY = f"arn:aws:iam::{ACCOUNT}:policy/fogiac-boundary"
ROLE = f"arn:aws:iam::{ACCOUNT}:role/fogiac/robots-dev/fogiac-robots-dev-flow-logs"  # where stacks/aws/ puts it
FOREIGN_ROLE = f"arn:aws:iam::{ACCOUNT}:role/admin"
INSTANCE = f"arn:aws:ec2:us-west-2:{ACCOUNT}:instance/i-0123456789abcdef0"
CALLER = {"aws:PrincipalAccount": [ACCOUNT]}
TAGGED = {**CALLER, "aws:ResourceTag/fogiac:stack": ["robots-dev"]}


def _decide(action: str, resource: str, **context: list[str]) -> str:
    return decide(iam.policy(), action, resource, {**CALLER, **context})


def test_a_role_without_the_boundary_cannot_be_created() -> None:
    """The escalation: a role that trusts the caller, with an admin inline policy, then assumed."""
    tag = {"aws:RequestTag/fogiac:stack": ["robots-dev"]}
    assert _decide("iam:CreateRole", ROLE, **tag) == "implicitDeny"
    assert _decide("iam:CreateRole", ROLE, **tag, **{"iam:PermissionsBoundary": [
        f"arn:aws:iam::{ACCOUNT}:policy/AdministratorAccess"]}) == "implicitDeny"
    assert _decide("iam:CreateRole", ROLE, **{"iam:PermissionsBoundary": [BOUNDARY]}) == "implicitDeny"  # untagged
    assert _decide("iam:CreateRole", FOREIGN_ROLE, **tag, **{"iam:PermissionsBoundary": [BOUNDARY]}) == "implicitDeny"
    assert _decide("iam:CreateRole", ROLE, **tag, **{"iam:PermissionsBoundary": [BOUNDARY]}) == "allowed"


def test_an_inline_policy_goes_only_on_a_role_under_the_boundary() -> None:
    for action in ("iam:PutRolePolicy", "iam:DeleteRolePolicy", "iam:DetachRolePolicy"):
        assert _decide(action, ROLE) == "implicitDeny", action  # a role without the boundary
        assert _decide(action, ROLE, **{"iam:PermissionsBoundary": [BOUNDARY]}) == "allowed", action
    for action in ("iam:AttachRolePolicy", "iam:PutRolePermissionsBoundary", "iam:DeleteRolePermissionsBoundary",
                   "iam:CreatePolicyVersion", "iam:CreateUser", "iam:AttachUserPolicy", "sts:AssumeRole"):
        assert _decide(action, ROLE, **{"iam:PermissionsBoundary": [BOUNDARY]}) == "implicitDeny", action


def test_the_boundary_leaves_a_role_nothing_but_writing_logs() -> None:
    """Even an inline ``*`` policy on a role fogiac made: what it may do is what both documents allow."""
    boundary = json.loads(iam.BOUNDARY_FILE.read_text())
    group = f"arn:aws:logs:us-west-2:{ACCOUNT}:log-group:/fogiac/robots-dev/flow-logs:log-stream:eni-1"
    assert decide(boundary, "logs:PutLogEvents", group) == "allowed"
    for action, resource in (("iam:CreateRole", FOREIGN_ROLE), ("ec2:TerminateInstances", INSTANCE),
                             ("logs:PutLogEvents", f"arn:aws:logs:us-west-2:{ACCOUNT}:log-group:audit:log-stream:x"),
                             ("s3:GetObject", "arn:aws:s3:::secrets/key")):
        assert decide(boundary, action, resource) == "implicitDeny", action


def test_only_fogiacs_own_roles_are_passed_and_only_to_flow_logs() -> None:
    flow_logs = {"iam:PassedToService": ["vpc-flow-logs.amazonaws.com"]}
    assert _decide("iam:PassRole", FOREIGN_ROLE, **flow_logs, **TAGGED) == "implicitDeny"
    assert _decide("iam:PassRole", ROLE, **flow_logs) == "implicitDeny"  # under fogiac's path, but untagged
    assert _decide("iam:PassRole", ROLE, **TAGGED, **{"iam:PassedToService": ["ec2.amazonaws.com"]}) == "implicitDeny"
    assert _decide("iam:PassRole", ROLE, **TAGGED, **flow_logs) == "allowed"
    assert _decide("iam:UpdateAssumeRolePolicy", ROLE) == "implicitDeny"  # an untagged role's trust
    assert _decide("iam:UpdateAssumeRolePolicy", FOREIGN_ROLE, **TAGGED) == "implicitDeny"


@pytest.mark.parametrize("action", ["ec2:TerminateInstances", "ec2:StopInstances", "ec2:StartInstances",
                                    "ec2:ModifyInstanceAttribute", "ec2:ModifyInstanceMetadataOptions"])
def test_an_untagged_instance_cannot_be_terminated_stopped_or_changed(action: str) -> None:
    assert _decide(action, INSTANCE) == "implicitDeny"
    assert _decide(action, INSTANCE, **{"aws:ResourceTag/Name": ["prod-db"]}) == "implicitDeny"
    assert _decide(action, INSTANCE, **TAGGED) == "allowed"


def test_no_destructive_action_is_granted_without_the_stack_tag() -> None:
    """Every Delete, Terminate, Stop, Modify, Detach, Disassociate, Revoke, Release and Replace the policy
    names is denied on a resource without ``fogiac:stack``."""
    destructive = sorted(a for a in iam.allowed() if re.match(r"[a-z0-9]+:(Delete|Terminate|Stop|Modify|Detach|"
                                                              r"Disassociate|Revoke|Release|Replace|Untag|Remove)", a))
    assert "ec2:DeleteVpc" in destructive and "logs:DeleteLogGroup" in destructive
    resource = f"arn:aws:ec2:us-west-2:{ACCOUNT}:anything/x"
    for action in destructive:
        context = {"iam:PermissionsBoundary": [BOUNDARY]} if action.startswith("iam:") else {}
        if action in ("iam:DeleteRolePolicy", "iam:DetachRolePolicy"):
            continue  # a role's policies: guarded by its boundary, above
        assert _decide(action, ROLE if action.startswith("iam:") else resource, **context) == "implicitDeny", action


def test_tags_are_given_at_creation_and_never_put_on_what_fogiac_did_not_create() -> None:
    stack_tag = {"aws:RequestTag/fogiac:stack": ["robots-dev"], "aws:TagKeys": ["fogiac:stack", "Name"]}
    assert _decide("ec2:CreateTags", INSTANCE, **stack_tag, **{"ec2:CreateAction": ["RunInstances"]}) == "allowed"
    assert _decide("ec2:CreateTags", INSTANCE, **stack_tag) == "implicitDeny"  # claiming a foreign instance
    assert _decide("ec2:CreateTags", INSTANCE, **{"aws:TagKeys": ["Name"]}) == "implicitDeny"
    assert _decide("ec2:CreateTags", INSTANCE, **TAGGED, **{"aws:TagKeys": ["Name"]}) == "allowed"  # its own
    assert _decide("ec2:DeleteTags", INSTANCE, **TAGGED, **{"aws:TagKeys": ["fogiac:stack"]}) == "implicitDeny"
    assert _decide("ec2:DeleteTags", INSTANCE, **TAGGED) == "implicitDeny"  # no keys: every tag
    assert _decide("ec2:CreateTags", INSTANCE, **TAGGED, **{"aws:TagKeys": ["fogiac:stack"]}) == "implicitDeny"


def test_every_action_fogiac_needs_is_allowed_on_its_own_requests() -> None:
    """The context doctor hands IAM's simulator (``iam.own_request``) passes every condition: what doctor
    asks is what the tests evaluate."""
    everything = iam.needed(iam.RESOURCE_ACTIONS)
    context = {**CALLER, **iam.own_request(ACCOUNT)}
    refused = sorted(a for a in everything
                     if decide(iam.policy(), a, ROLE if a.startswith("iam:") else "*", context) != "allowed")
    assert refused == []
