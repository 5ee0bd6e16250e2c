"""fogiac.targets.aws.tfplan: the offline plan as Terraform plan JSON, on every example, through the CLI."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.errors import PlanError
from fogiac.targets.aws import tfplan

REPO = Path(__file__).resolve().parents[3]
EXAMPLES = sorted((REPO / "examples").glob("*.yaml"))
CHECKOV = REPO / ".checkov-venv" / "bin" / "checkov"
runner = CliRunner()


def export(path: Path) -> dict[str, Any]:
    result = runner.invoke(app, ["plan", str(path), "--format", "terraform-json"])
    assert result.exit_code == 0, result.output
    exported: dict[str, Any] = json.loads(result.stdout)  # stderr holds the placeholder warnings (proxy.yaml)
    return exported


@pytest.fixture(scope="module")
def exported() -> dict[str, dict[str, Any]]:
    return {path.stem: export(path) for path in EXAMPLES}


def by_address(rows: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    return {row["address"]: row for row in rows}


def test_names_and_sections(exported: dict[str, dict[str, Any]]) -> None:
    assert set(exported) == {"grasp-planning", "minimal", "motion-planning", "proxy", "ros2-zenoh", "slam"}
    for doc in exported.values():
        assert doc["format_version"] == "1.2" and doc["terraform_version"].startswith("1.")
        planned = doc["planned_values"]["root_module"]["resources"]
        configured = doc["configuration"]["root_module"]["resources"]
        assert [r["address"] for r in planned] == [r["address"] for r in doc["resource_changes"]]
        assert [r["address"] for r in planned] == [r["address"] for r in configured]
        assert len(set(r["address"] for r in planned)) == len(planned)
        assert {r["change"]["actions"][0] for r in doc["resource_changes"]} == {"create"}
        assert all(r["address"] == f"{r['type']}.{r['name']}" for r in planned)
        assert set(r["type"] for r in planned) <= set(tfplan.TYPES.values())


def test_minimal_types_and_attributes(exported: dict[str, dict[str, Any]]) -> None:
    planned = by_address(exported["minimal"]["planned_values"]["root_module"]["resources"])
    assert planned["aws_vpc.minimal-dev-vpc"]["values"]["cidr_block"] == "10.10.0.0/16"
    assert planned["aws_vpc.minimal-dev-vpc"]["values"]["tags"]["fogiac:stack"] == "minimal-dev"  # a map
    hosts = planned["aws_subnet.minimal-dev-subnet-hosts"]["values"]
    assert hosts["map_public_ip_on_launch"] is False and "vpc_id" not in hosts  # unknown until apply
    instance = planned["aws_instance.minimal-dev-host-talker"]["values"]
    assert instance["metadata_options"] == [
        {"http_endpoint": "enabled", "http_put_response_hop_limit": 2, "http_tokens": "required"}
    ]
    assert instance["root_block_device"][0]["encrypted"] is True  # a nested block: a list of objects
    assert instance["ebs_optimized"] is True and instance["associate_public_ip_address"] is True
    route = planned["aws_route_table.minimal-dev-rt-public"]["values"]["route"]  # Pulumi's "routes"
    assert route == [{"cidr_block": "0.0.0.0/0"}]
    endpoint = planned["aws_ec2_client_vpn_endpoint.minimal-dev-endpoint"]["values"]
    assert endpoint["connection_log_options"] == [
        {"enabled": True, "cloudwatch_log_group": "/fogiac/minimal-dev/client-vpn"}
    ]
    egress = [r["values"] for r in planned.values() if r["type"] == "aws_vpc_security_group_egress_rule"
              and r["values"].get("cidr_ipv4") == "0.0.0.0/0"]
    assert sorted((r["ip_protocol"], r["from_port"]) for r in egress) == [("tcp", 80), ("tcp", 443)]
    assert "aws_default_security_group.minimal-dev-default-sg" in planned
    certificate = planned["aws_acm_certificate.minimal-dev-cert-server"]["values"]
    assert certificate["private_key"] == "[secret]"


def test_references_show_which_group_guards_which_instance(exported: dict[str, dict[str, Any]]) -> None:
    doc = exported["minimal"]
    configured = by_address(doc["configuration"]["root_module"]["resources"])
    instance = configured["aws_instance.minimal-dev-host-talker"]["expressions"]
    assert instance["vpc_security_group_ids"] == {
        "references": ["aws_security_group.minimal-dev-sg-hosts.id", "aws_security_group.minimal-dev-sg-hosts"]
    }
    assert instance["subnet_id"]["references"][1] == "aws_subnet.minimal-dev-subnet-hosts"
    assert instance["instance_type"] == {"constant_value": "t3.small"}
    default = configured["aws_default_security_group.minimal-dev-default-sg"]["expressions"]
    assert default["vpc_id"]["references"] == ["aws_vpc.minimal-dev-vpc.id", "aws_vpc.minimal-dev-vpc"]
    route = configured["aws_route_table.minimal-dev-rt-public"]["expressions"]["route"]
    assert route[0]["gateway_id"]["references"][1] == "aws_internet_gateway.minimal-dev-igw"
    changes = by_address(doc["resource_changes"])
    unknown = changes["aws_instance.minimal-dev-host-talker"]["change"]["after_unknown"]
    assert unknown["vpc_security_group_ids"] == [True] and unknown["subnet_id"] is True


def test_flow_logs_reference_the_vpc_and_drop_their_by_design_skip(exported: dict[str, dict[str, Any]]) -> None:
    proxy = exported["proxy"]  # the example with network.flow_logs: true
    configured = by_address(proxy["configuration"]["root_module"]["resources"])
    flow = configured["aws_flow_log.proxy-demo-dev-flow-log"]["expressions"]
    assert flow["vpc_id"]["references"][1] == "aws_vpc.proxy-demo-dev-vpc"
    assert flow["log_destination"]["references"][1] == "aws_cloudwatch_log_group.proxy-demo-dev-flow-logs"
    assert flow["iam_role_arn"]["references"][1] == "aws_iam_role.proxy-demo-dev-flow-logs-role"
    checks = {d["check"] for d in proxy["fogiac"]["by_design"]}
    assert checks == {"CKV_AWS_88", "CKV2_AWS_41", "CKV_AWS_126", "CKV_AWS_158"}
    assert {d["check"] for d in exported["minimal"]["fogiac"]["by_design"]} == checks | {"CKV2_AWS_11"}
    assert all(d["reason"].endswith(".") and d["reason"].count(". ") == 0 for d in proxy["fogiac"]["by_design"])


def test_unknown_type_is_named() -> None:
    with pytest.raises(PlanError, match=r"no Terraform type known for 'aws:s3/bucket:Bucket'; add it to"):
        tfplan.tf_type("aws:s3/bucket:Bucket")


def test_a_target_without_an_exporter_says_so() -> None:
    result = runner.invoke(app, ["plan", str(REPO / "examples" / "minimal.yaml"), "--target", "local",
                                 "--format", "terraform-json"])
    assert result.exit_code == 1
    assert ("target 'local' cannot export its plan as 'terraform-json'; available: aws (terraform-json)"
            in result.output)


def test_same_manifest_same_export(exported: dict[str, dict[str, Any]]) -> None:
    assert export(REPO / "examples" / "minimal.yaml") == exported["minimal"]


@pytest.mark.skipif(not CHECKOV.exists(), reason="no .checkov-venv (bash .ci/checkov.sh makes it)")
def test_checkov_finds_nothing_but_the_declared_checks(exported: dict[str, dict[str, Any]], tmp_path: Path) -> None:
    """The CI gate's claim, for two examples (vpn mode without flow logs, proxy mode with them)."""
    for name in ("minimal", "proxy"):
        plan = tmp_path / f"{name}.json"
        plan.write_text(json.dumps(exported[name]))
        result = subprocess.run([str(CHECKOV), "-f", str(plan), "--framework", "terraform_plan", "--output", "json"],
                                capture_output=True, text=True, timeout=300)
        report = json.loads(result.stdout)
        failed = {c["check_id"] for c in report["results"]["failed_checks"]}
        assert failed == {d["check"] for d in exported[name]["fogiac"]["by_design"]}, name
        passed = {c["check_id"] for c in report["results"]["passed_checks"]}
        assert {"CKV2_AWS_12", "CKV_AWS_130", "CKV_AWS_135", "CKV_AWS_79", "CKV_AWS_8"} <= passed, name
        if name == "proxy":
            assert "CKV2_AWS_11" in passed


def test_the_docs_give_every_by_design_reason() -> None:
    readme = (REPO / "docs" / "guides" / "pull-requests.md").read_text()
    for check, _, reason in tfplan.BY_DESIGN:
        assert f"`{check}`" in readme and reason in readme.replace("\n", " "), check


def test_against_another_manifest_gives_terraform_actions_and_before(tmp_path: Path) -> None:
    base = (REPO / "examples" / "minimal.yaml").read_text()
    (tmp_path / "base.yaml").write_text(base)
    (tmp_path / "head.yaml").write_text(base.replace("t3.small", "t3.medium"))
    result = runner.invoke(app, ["plan", str(tmp_path / "head.yaml"), "--against", str(tmp_path / "base.yaml"),
                                 "--format", "terraform-json"])
    assert result.exit_code == 0, result.output
    changes = by_address(json.loads(result.output)["resource_changes"])
    instance = changes["aws_instance.minimal-dev-host-talker"]["change"]
    assert instance["actions"] == ["update"]
    assert (instance["before"]["instance_type"], instance["after"]["instance_type"]) == ("t3.small", "t3.medium")
    assert changes["aws_vpc.minimal-dev-vpc"]["change"]["actions"] == ["no-op"]
