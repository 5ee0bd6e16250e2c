"""preflight against LocalStack: zones, GPUs, images, conflicts, and one line per problem."""

from __future__ import annotations

from pathlib import Path

import pytest

from fogiac.targets.aws.api import preflight, resolve_image
from fogiac.targets.aws.placement import UBUNTU
from fogiac.errors import CredentialsError, PreflightError

from .conftest import NEWEST_UBUNTU
from .plans import make_plan, with_region

pytestmark = pytest.mark.localstack


def test_picks_first_zone_offering_every_type(ec2, tmp_path: Path) -> None:
    plan = make_plan(tmp_path, "pf-zone", nodes=(("cpu", "t3.small"), ("gpu", "g5.xlarge")))
    report = preflight(plan, ec2=ec2)
    assert report.zone == "us-west-2a"
    assert report.account == "000000000000"
    assert report.operator_cidrs == ("203.0.113.7/32",)
    assert dict(report.images)["cpu"] == NEWEST_UBUNTU
    assert dict(report.images)["gpu"] == "ami-0a1b2c3d4e5f60003"


def test_chosen_zone_must_offer_every_type(ec2, tmp_path: Path) -> None:
    plan = make_plan(tmp_path, "pf-chosen", nodes=(("gpu", "g5.xlarge"),), zone="us-west-2d")
    with pytest.raises(PreflightError, match=r"^zone us-west-2d does not offer g5.xlarge "
                                             r"\(zones that do: us-west-2a, us-west-2b, us-west-2c\)$"):
        preflight(plan, ec2=ec2)


def test_zone_offers_the_type_a_requirement_resolved_to(ec2, tmp_path: Path) -> None:
    plan = make_plan(tmp_path, "pf-req", nodes=(("gpu", "{gpu: A10G, vcpus: 4}"),), zone="us-west-2d")
    assert plan.host("gpu").machine == "g5.xlarge"
    with pytest.raises(PreflightError, match=r"^zone us-west-2d does not offer g5.xlarge "):
        preflight(plan, ec2=ec2)
    report = preflight(make_plan(tmp_path, "pf-req2", nodes=(("gpu", "{gpu: A10G, vcpus: 4}"),)), ec2=ec2)
    assert report.zone == "us-west-2a"


def test_type_not_offered_in_region(ec2, tmp_path: Path) -> None:
    plan = make_plan(tmp_path, "pf-p3", nodes=(("gpu", "p3.2xlarge"),))
    with pytest.raises(PreflightError, match=r"^machine type p3.2xlarge is not offered in us-west-2$"):
        preflight(plan, ec2=ec2)


def test_unknown_region_is_one_line(aws_env: str, tmp_path: Path) -> None:
    plan = with_region(make_plan(tmp_path, "pf-region"), "mars-north-1")
    with pytest.raises(PreflightError, match=r"^unknown AWS region 'mars-north-1'$"):
        preflight(plan)


def test_missing_credentials_is_one_line(aws_env: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("AWS_ACCESS_KEY_ID")
    monkeypatch.delenv("AWS_SECRET_ACCESS_KEY")
    with pytest.raises(CredentialsError, match=r"^no AWS credentials found: set AWS_PROFILE"):
        preflight(make_plan(tmp_path, "pf-creds"))


def test_every_problem_reported_together(ec2, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("FOGIAC_OPERATOR_CIDR")
    plan = make_plan(tmp_path, "pf-many", nodes=(("gpu", "g5.xlarge"),), zone="us-west-2d")
    with pytest.raises(PreflightError) as info:
        preflight(plan, ec2=ec2, fetch_address=False)
    assert str(info.value).splitlines() == [
        "zone us-west-2d does not offer g5.xlarge (zones that do: us-west-2a, us-west-2b, us-west-2c)",
        "ssh_from: auto needs your address: pass --ssh-from CIDR or set FOGIAC_OPERATOR_CIDR",
    ]


def test_operator_override_must_be_an_address(ec2, tmp_path: Path) -> None:
    with pytest.raises(PreflightError, match=r"^--ssh-from 'my laptop' is not an address or CIDR$"):
        preflight(make_plan(tmp_path, "pf-ssh"), ec2=ec2, operator_cidr="my laptop")


def test_resources_outside_state_are_a_conflict(ec2, tmp_path: Path) -> None:
    plan = make_plan(tmp_path, "pf-conflict")
    vpc = ec2.create_vpc(CidrBlock="10.50.0.0/16", TagSpecifications=[
        {"ResourceType": "vpc", "Tags": [{"Key": "fogiac:stack", "Value": plan.stack}]}])["Vpc"]["VpcId"]
    try:
        with pytest.raises(PreflightError, match=rf"^stack pf-conflict-dev already has resources outside "
                                                 rf"fogiac's state \({vpc}\); run `fogiac sweep`"):
            preflight(plan, ec2=ec2)
        assert preflight(plan, ec2=ec2, known_ids={vpc}).zone == "us-west-2a"
    finally:
        ec2.delete_vpc(VpcId=vpc)


def test_newest_image_wins(ec2) -> None:
    assert resolve_image(ec2, UBUNTU) == NEWEST_UBUNTU
