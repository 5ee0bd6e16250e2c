"""Issue 27: the IAM policy fogiac ships allows every AWS call fogiac makes and every action the
provider needs for each resource type an example declares, and ``doctor`` checks it: against
IAM's policy simulator (LocalStack) with credentials, offline without."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Any

import pytest

from fogiac import targets
from fogiac.manifest.schema import load_manifest, parse_manifest
from fogiac.plan.compile import compile_plan
from fogiac.targets.aws import iam
from fogiac.targets.base import Check
from tests.conftest import EXAMPLES, REPO

SERVICES = {"ec2": "ec2", "sts": "sts", "acm": "acm", "logs": "logs", "iam": "iam",
            "service-quotas": "servicequotas", "pricing": "pricing"}


def _calls_fogiac_makes() -> set[str]:
    """Every botocore operation of the services fogiac uses that the aws target's code names (method or paginator)."""
    botocore = pytest.importorskip("botocore.session")
    from botocore import xform_name

    session = botocore.get_session()
    text = "\n".join(p.read_text() for p in (REPO / "fogiac" / "targets" / "aws").glob("*.py"))
    words = set(re.findall(r"\b([a-z][a-z0-9]*(?:_[a-z0-9]+)+)\b", text))
    found = set()
    for service, prefix in SERVICES.items():
        for operation in session.get_service_model(service).operation_names:
            if xform_name(operation) in words:
                found.add(f"{prefix}:{operation}")
    return found


def test_the_policy_allows_every_call_fogiac_makes() -> None:
    calls = _calls_fogiac_makes()
    assert {"sts:GetCallerIdentity", "ec2:DescribeInstances", "ec2:DeleteVpc", "acm:DeleteCertificate",
            "servicequotas:GetServiceQuota"} <= calls  # the scan finds what it should
    assert calls - iam.allowed() == set()


def _declared_types(example: Path) -> set[str]:
    plan = compile_plan(load_manifest(example))
    return {str(r["type"]) for r in targets.get("aws").declare(plan)}


@pytest.mark.parametrize("example", sorted(p.name for p in EXAMPLES.glob("*.yaml")))
def test_the_policy_allows_what_each_declared_resource_type_needs(example: str) -> None:
    types = _declared_types(EXAMPLES / example)
    assert types and types <= set(iam.RESOURCE_ACTIONS), types - set(iam.RESOURCE_ACTIONS)
    assert iam.needed(types) - iam.allowed() == set()


def test_the_policy_is_a_valid_document_scoped_where_it_can_be() -> None:
    document = json.loads(iam.POLICY_FILE.read_text())
    assert document["Version"] == "2012-10-17"
    for statement in document["Statement"]:
        assert statement["Effect"] == "Allow" and all(":" in a for a in statement["Action"]), statement
        if statement["Action"] == ["iam:GetPolicy"]:  # doctor reads the one boundary policy, nothing else
            assert statement["Resource"] == "arn:aws:iam::*:policy/fogiac-boundary", statement
        elif any(a.startswith("iam:") and a != "iam:SimulatePrincipalPolicy" and a != "iam:ListRoles"
               for a in statement["Action"]):
            # only fogiac's own roles: stacks/aws/ puts them under the path /fogiac/<stack>/ (issue 35 item 4: the
            # pattern was role/fogiac-*, which that path's ARN role/fogiac/<stack>/... never matched)
            assert statement["Resource"] == "arn:aws:iam::*:role/fogiac/*", statement


def test_doctor_without_credentials_checks_nothing_and_names_the_policy(monkeypatch: pytest.MonkeyPatch) -> None:
    for key in [k for k in os.environ if k.startswith("AWS_")]:
        monkeypatch.delenv(key)
    monkeypatch.setenv("AWS_CONFIG_FILE", os.devnull)
    monkeypatch.setenv("AWS_SHARED_CREDENTIALS_FILE", os.devnull)
    monkeypatch.setenv("AWS_EC2_METADATA_DISABLED", "true")
    monkeypatch.setenv("AWS_ENDPOINT_URL", "http://127.0.0.1:9")  # were anything sent, it would fail differently
    plan = compile_plan(load_manifest(EXAMPLES / "minimal.yaml"))
    check = iam.doctor_check(plan, _declared_types(EXAMPLES / "minimal.yaml"))
    assert check.ok and check.what == "IAM policy"
    assert check.detail.startswith("not checked (no AWS credentials found")
    assert "`python -m fogiac.targets.aws.iam`" in check.detail


def test_doctor_against_localstack_says_when_the_simulator_cannot_answer(aws_env: str) -> None:
    """LocalStack's IAM has no working policy simulator: a real call, answered with an error, is "not checked"."""
    plan = compile_plan(load_manifest(EXAMPLES / "minimal.yaml"))
    check = iam.doctor_check(plan, _declared_types(EXAMPLES / "minimal.yaml"))
    assert check.ok and check.detail.startswith("not checked (IAM's policy simulator answered "), check.detail


def _stubbed(service: str) -> tuple[Any, Any]:
    from botocore.stub import Stubber

    from fogiac.targets.aws.api import client

    made = client(service, region="us-west-2")
    return made, Stubber(made)


def test_doctor_names_the_actions_an_assumed_role_is_denied(monkeypatch: pytest.MonkeyPatch) -> None:
    """The simulator's answers (AWS's shapes, stubbed: LocalStack has none) become one line naming the denied."""
    monkeypatch.setenv("AWS_ACCESS_KEY_ID", "test")
    monkeypatch.setenv("AWS_SECRET_ACCESS_KEY", "test")
    types = _declared_types(EXAMPLES / "minimal.yaml")
    wanted = sorted(iam.needed(types))
    sts, sts_stub = _stubbed("sts")
    client, iam_stub = _stubbed("iam")
    sts_stub.add_response("get_caller_identity", {
        "Arn": "arn:aws:sts::123456789012:assumed-role/ci-deployer/session-1", "Account": "123456789012",
        "UserId": "AROA:session-1"})
    for start in range(0, len(wanted), 100):
        batch = wanted[start:start + 100]
        iam_stub.add_response("simulate_principal_policy", {"EvaluationResults": [
            {"EvalActionName": a, "EvalDecision": "implicitDeny" if a in ("ec2:RunInstances", "iam:PassRole")
             else "allowed"} for a in batch]},
            {"PolicySourceArn": "arn:aws:iam::123456789012:role/ci-deployer", "ActionNames": batch,
             "ContextEntries": [{"ContextKeyName": key, "ContextKeyValues": values,
                                 "ContextKeyType": "stringList" if len(values) > 1 or key == "aws:TagKeys"
                                 else "string"} for key, values in iam.own_request("123456789012").items()]})
    plan = compile_plan(load_manifest(EXAMPLES / "minimal.yaml"))
    with sts_stub, iam_stub:
        check = iam.doctor_check(plan, types, sts=sts, iam=client)
    denied = sorted({"ec2:RunInstances", "iam:PassRole"} & set(wanted))
    assert not check.ok
    assert check.detail.startswith(f"{len(denied)} of the {len(wanted)} actions this plan needs are denied: "
                                   f"{', '.join(denied)}; ")
    iam_stub.assert_no_pending_responses()


def _flow_logs(text: str) -> str:
    """A manifest whose network makes a role (the flow logs' role, with the boundary on it)."""
    return text.replace("nodes:\n", "network:\n  flow_logs: true\nnodes:\n", 1)


def test_doctor_checks_the_permissions_boundary_exists(aws_env: str) -> None:
    """Issue 35 (item 4's boundary): doctor said nothing of fogiac-boundary, so a plan with flow_logs failed at up,
    after the VPC was made, when the account had none. On LocalStack's IAM: missing, then made."""
    from fogiac.targets.aws.api import client

    minimal = (EXAMPLES / "minimal.yaml").read_text()
    logged = parse_manifest(_flow_logs(minimal))
    plan, plain = compile_plan(logged), compile_plan(parse_manifest(minimal))
    roles = {str(r["type"]) for r in targets.get("aws").declare(plan)}
    assert set(iam.ROLE_TYPES) <= roles
    arn = "arn:aws:iam::000000000000:policy/fogiac-boundary"
    missing = iam.boundary_check(plan, roles)
    assert (missing.what, missing.ok) == ("permissions boundary", False)
    assert missing.detail == (f"the account has no {arn}, which the role this plan makes (flow_logs: true) must "
                              "carry, or up fails: an administrator creates it once from `python -m "
                              "fogiac.targets.aws.iam --boundary`")
    unneeded = iam.boundary_check(plain, _declared_types(EXAMPLES / "minimal.yaml"))
    assert unneeded.ok and "this plan makes no role, so it needs none" in unneeded.detail
    account = client("iam", region="us-east-1")
    made = account.create_policy(PolicyName="fogiac-boundary", PolicyDocument=iam.BOUNDARY_FILE.read_text())
    try:
        assert made["Policy"]["Arn"] == arn
        assert iam.boundary_check(plan, roles) == Check("permissions boundary", True, f"{arn} exists")
    finally:
        account.delete_policy(PolicyArn=arn)  # the emulator is shared: cli doctor's test expects none


def test_doctor_without_credentials_does_not_check_the_boundary(monkeypatch: pytest.MonkeyPatch) -> None:
    for key in [k for k in os.environ if k.startswith("AWS_")]:
        monkeypatch.delenv(key)
    monkeypatch.setenv("AWS_CONFIG_FILE", os.devnull)
    monkeypatch.setenv("AWS_SHARED_CREDENTIALS_FILE", os.devnull)
    monkeypatch.setenv("AWS_EC2_METADATA_DISABLED", "true")
    monkeypatch.setenv("AWS_ENDPOINT_URL", "http://127.0.0.1:9")
    check = iam.boundary_check(compile_plan(load_manifest(EXAMPLES / "minimal.yaml")), set(iam.ROLE_TYPES))
    assert check.ok and check.detail.startswith("not checked (no AWS credentials found")
    assert "`python -m fogiac.targets.aws.iam --boundary`" in check.detail
