"""EC2 vCPU quotas per family, read before anything is created (botocore's Stubber: LocalStack has no
Service Quotas)."""

from __future__ import annotations

from typing import Any

import pytest

from fogiac.targets.aws.quotas import FAMILIES, Machine, QuotaUnavailable, check, demand, family_of, report

boto3 = pytest.importorskip("boto3")
stub = pytest.importorskip("botocore.stub")

REGION = "us-east-1"


def _client(service: str) -> tuple[Any, Any]:
    client = boto3.session.Session(region_name=REGION, aws_access_key_id="test",
                                   aws_secret_access_key="test").client(service)
    stubber = stub.Stubber(client)
    return client, stubber


def _quota(stubber: Any, code: str, value: float) -> None:
    stubber.add_response("get_service_quota", {"Quota": {"QuotaCode": code, "Value": value, "ServiceCode": "ec2"}},
                         {"ServiceCode": "ec2", "QuotaCode": code})


def test_families_follow_the_leading_letters() -> None:
    assert family_of("g5.xlarge").on_demand == "L-DB2E81BA"
    assert family_of("vt1.3xlarge").name == "g"
    assert family_of("p4d.24xlarge").on_demand == "L-417A185B"
    assert family_of("p5.48xlarge").spot == "L-7212CCBC"
    assert family_of("x2idn.16xlarge").on_demand == "L-7295265B"
    assert family_of("dl1.24xlarge").name == "dl"  # not the D of the standard family
    assert family_of("inf2.xlarge").name == "inf" and family_of("trn1.2xlarge").name == "trn"
    for standard in ("c5.24xlarge", "m7i.large", "t2.micro", "r6g.large", "z1d.large", "hpc7a.96xlarge"):
        assert family_of(standard).on_demand == "L-1216C47A", standard
    assert FAMILIES["standard"].spot == "L-34B43A08" and FAMILIES["g"].spot == "L-3819A6DF"


def test_machines_group_by_family_and_purchase() -> None:
    groups = demand([Machine("a", "g5.xlarge", 4), Machine("b", "c5.large", 2),
                     Machine("c", "g6.xlarge", 4, spot=True), Machine("d", "g4dn.xlarge", 4)])
    assert {k: [m.name for m in v] for k, v in groups.items()} == {
        ("g", False): ["a", "d"], ("standard", False): ["b"], ("g", True): ["c"]}


def test_a_new_accounts_zero_gpu_quota_is_named_before_anything_is_created() -> None:
    quotas, stubber = _client("service-quotas")
    _quota(stubber, "L-DB2E81BA", 0.0)
    _quota(stubber, "L-1216C47A", 32.0)
    stubber.activate()
    plan = [Machine("detector", "g5.xlarge", 4), Machine("planner", "c5.24xlarge", 96),
            Machine("relay", "t3.small", 2)]
    lines = report(check(plan, region=REGION, quotas=quotas))
    stubber.assert_no_pending_responses()
    assert lines == [
        "detector (g5.xlarge, 4 vCPU) would exceed the on-demand G and VT vCPU quota in us-east-1: "
        "L-DB2E81BA allows 0, the plan needs 4; ask for more: aws service-quotas request-service-quota-increase "
        "--region us-east-1 "
        "--service-code ec2 --quota-code L-DB2E81BA --desired-value 4",
        "planner (c5.24xlarge, 96 vCPU) would exceed the on-demand Standard (A, C, D, H, I, M, R, T, Z) vCPU quota in "
        "us-east-1: L-1216C47A allows 32, the plan needs 96; ask for more: aws service-quotas "
        "request-service-quota-increase --region us-east-1 --service-code ec2 --quota-code L-1216C47A "
        "--desired-value 96",
        "relay (t3.small, 2 vCPU) would exceed the on-demand Standard (A, C, D, H, I, M, R, T, Z) vCPU quota in "
        "us-east-1: L-1216C47A allows 32, the plan needs 98; ask for more: aws service-quotas "
        "request-service-quota-increase --region us-east-1 --service-code ec2 --quota-code L-1216C47A "
        "--desired-value 98",
    ]


def test_spot_machines_use_the_spot_quota_and_running_vcpus_count() -> None:
    quotas, qs = _client("service-quotas")
    _quota(qs, "L-3819A6DF", 8.0)
    qs.activate()
    ec2, es = _client("ec2")
    es.add_response("describe_instances", {"Reservations": [{"Instances": [
        {"InstanceType": "g4dn.xlarge", "InstanceLifecycle": "spot",
         "CpuOptions": {"CoreCount": 2, "ThreadsPerCore": 2}},
        {"InstanceType": "m5.large", "CpuOptions": {"CoreCount": 1, "ThreadsPerCore": 2}},
    ]}]}, {"Filters": [{"Name": "instance-state-name", "Values": ["pending", "running"]}]})
    es.activate()
    short = check([Machine("cam", "g6.xlarge", 4, spot=True), Machine("cam2", "g6.xlarge", 4, spot=True)],
                  region=REGION, quotas=quotas, ec2=ec2)
    assert [(s.machine.name, s.quota.code, s.quota.in_use, s.needed) for s in short] == [
        ("cam2", "L-3819A6DF", 4.0, 12.0)]
    assert "spot G and VT vCPU quota" in short[0].line() and "4 in use" in short[0].line()


def test_a_quota_the_account_never_set_falls_back_to_the_aws_default() -> None:
    quotas, stubber = _client("service-quotas")
    stubber.add_client_error("get_service_quota", service_error_code="NoSuchResourceException",
                             expected_params={"ServiceCode": "ec2", "QuotaCode": "L-417A185B"})
    stubber.add_response("get_aws_default_service_quota",
                         {"Quota": {"QuotaCode": "L-417A185B", "Value": 0.0, "ServiceCode": "ec2"}},
                         {"ServiceCode": "ec2", "QuotaCode": "L-417A185B"})
    stubber.activate()
    short = check([Machine("trainer", "p4d.24xlarge", 96)], region=REGION, quotas=quotas)
    assert len(short) == 1 and short[0].quota.default and short[0].quota.limit == 0


def test_fits_report_nothing_and_an_unknown_quota_is_not_read_as_zero() -> None:
    quotas, stubber = _client("service-quotas")
    _quota(stubber, "L-1216C47A", 640.0)
    stubber.add_client_error("get_service_quota", service_error_code="NoSuchResourceException",
                             expected_params={"ServiceCode": "ec2", "QuotaCode": "L-DB2E81BA"})
    stubber.add_client_error("get_aws_default_service_quota", service_error_code="NoSuchResourceException")
    stubber.activate()
    assert check([Machine("a", "m5.large", 2), Machine("b", "g5.xlarge", 4)], region=REGION, quotas=quotas) == []


def test_no_permission_is_one_line() -> None:
    quotas, stubber = _client("service-quotas")
    stubber.add_client_error("get_service_quota", service_error_code="AccessDeniedException")
    stubber.activate()
    with pytest.raises(QuotaUnavailable, match=r"^cannot read EC2 vCPU quotas in us-east-1: the credentials lack "
                       r"servicequotas:GetServiceQuota \(add it, or skip the check\)$"):
        check([Machine("a", "m5.large", 2)], region=REGION, quotas=quotas)


PLAN = """\
name: quota
cloud: {region: us-east-1}
nodes:
  - {name: planner, machine: c5.24xlarge, image: "ros:noetic"}
  - {name: grasp, machine: g5.xlarge, image: "ros:noetic"}
"""


def _plan() -> Any:
    from fogiac.manifest.schema import parse_manifest
    from fogiac.plan.compile import compile_plan

    return compile_plan(parse_manifest(PLAN, source="quota.yaml"), target="aws")


def test_doctor_names_the_exceeded_quota_and_up_refuses_before_creating(monkeypatch: pytest.MonkeyPatch) -> None:
    from fogiac.errors import CloudError
    from fogiac.targets.aws import api, quotas
    from fogiac.targets.aws.target import AWS

    plan = _plan()
    client, stubber = _client("service-quotas")
    _quota(stubber, "L-1216C47A", 96)  # standard: c5.24xlarge's 96 vCPUs fit
    _quota(stubber, "L-DB2E81BA", 0)  # G and VT: a new account's 0
    with stubber:
        checks = quotas.doctor_checks(plan, quotas=client)
    assert [(c.what, c.ok, c.detail) for c in checks] == [(
        "vCPU quotas", False,
        "grasp (g5.xlarge, 4 vCPU) would exceed the on-demand G and VT vCPU quota in us-east-1: L-DB2E81BA allows 0, "
        "the plan needs 4; ask for more: aws service-quotas request-service-quota-increase --region us-east-1 "
        "--service-code ec2 --quota-code L-DB2E81BA --desired-value 4")]

    # up: the preflight passes, then the quota check refuses before create is ever called
    monkeypatch.setattr(api, "preflight", lambda *a, **k: type("R", (), {"zone": "us-east-1a"})())
    monkeypatch.setattr("fogiac.targets.aws.target.engine.known_ids", lambda stack: frozenset())
    client, stubber = _client("service-quotas")
    _quota(stubber, "L-1216C47A", 96)
    _quota(stubber, "L-DB2E81BA", 0)
    monkeypatch.setattr(api, "client", lambda service, *, region: client)
    with stubber, pytest.raises(CloudError, match=r"^grasp \(g5\.xlarge, 4 vCPU\) would exceed the on-demand G and VT "):
        AWS.prepare(plan, ssh_from="203.0.113.7/32")


def test_doctor_says_when_quotas_cannot_be_read() -> None:
    from fogiac.targets.aws import quotas

    client, stubber = _client("service-quotas")
    stubber.add_client_error("get_service_quota", "AccessDeniedException", "no")
    with stubber:
        checks = quotas.doctor_checks(_plan(), quotas=client)
    assert [(c.ok, c.detail) for c in checks] == [(True, "not checked: cannot read EC2 vCPU quotas in us-east-1: the "
                                                         "credentials lack servicequotas:GetServiceQuota (add it, or "
                                                         "skip the check)")]
