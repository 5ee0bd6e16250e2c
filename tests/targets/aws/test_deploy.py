"""fogiac up and down end to end against LocalStack, the harness standing in for the Pulumi engine.

The engine cannot run here (no Pulumi CLI): a subclass of fogiac's Engine keeps everything but
the Automation API calls (the stack programs with the stack's real certificates and SSH key)
and hands the programs to the harness, which creates and deletes through boto3. The rest is
fogiac's real up and down: preflight, the lock, outputs and applied plan, the sweep of what no
state knows, the report of what is left, the exit status and the state files.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import pytest
from botocore.exceptions import ClientError
from typer.testing import CliRunner

from fogiac import deployment
from fogiac.certs import new_bundle
from fogiac.cli import app
from fogiac.state import read_json, stack_dir, write_json_atomic
from fogiac.pulumi_engine.engine import LayerResult
from fogiac.pulumi_engine.workspace import PULUMI_CLI_VERSION
from fogiac.targets.aws.engine import LAYERS, OUTPUTS_FILE, SSH_KEY_FILE, Engine
from fogiac.targets.aws.errors import EngineError

from .harness import Harness, InjectedFailure
from .plans import make_plan, write_manifest
from .test_apply import PUBLIC_KEY

pytestmark = pytest.mark.localstack


@pytest.fixture
def engine_is_harness(aws_env: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, ec2: Any, acm: Any) -> Harness:
    """A fake ``pulumi`` for the version check, and the harness as the engine's destroy."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "pulumi").write_text(f"#!/bin/sh\necho v{PULUMI_CLI_VERSION}\n")
    (bin_dir / "pulumi").chmod(0o755)
    monkeypatch.setenv("PATH", f"{bin_dir}:/usr/bin:/bin")
    monkeypatch.setenv("COLUMNS", "200")  # rich tables unabridged
    harness = Harness(ec2=ec2, acm=acm)

    class HarnessEngine(Engine):
        def up(self, *, operator_cidrs: tuple[str, ...]) -> dict[str, Any]:
            outputs: dict[str, Any] = {}
            programs = self.programs(operator_cidrs=operator_cidrs, network_outputs=lambda: outputs["network"])
            for layer in LAYERS:
                try:
                    outputs[layer] = harness.run_layer(self.plan, layer, programs[layer])
                except ClientError as err:  # what AWS refused reaches fogiac as the engine's error, as with Pulumi
                    raise EngineError(f"{layer} stack failed: {err}; `fogiac down` removes what was made") from None
            return outputs

        def destroy(self, *, layers: tuple[str, ...] = ("compute", "network")) -> list[str]:
            return harness.destroy(layers=layers)

        def refresh(self) -> list[LayerResult]:  # the engine reads back the outputs it made: outputs.json here
            made = read_json(stack_dir(self.plan.stack) / OUTPUTS_FILE) or {}
            return [LayerResult(layer, True, made[layer], "no changes") for layer in LAYERS if layer in made]

    monkeypatch.setattr("fogiac.targets.aws.engine.Engine", HarnessEngine)
    monkeypatch.setattr("fogiac.targets.aws.sweep.time.sleep", lambda s: None)  # bounded retries, without the waiting
    return harness


def _tagged(ec2: Any, stack: str) -> dict[str, list[str]]:
    flt = [{"Name": "tag:fogiac:stack", "Values": [stack]}]
    return {
        "vpcs": [v["VpcId"] for v in ec2.describe_vpcs(Filters=flt)["Vpcs"]],
        "instances": [i["InstanceId"] for r in ec2.describe_instances(Filters=flt + [
            {"Name": "instance-state-name", "Values": ["pending", "running", "stopped"]}])["Reservations"]
            for i in r["Instances"]],
        "keys": [k["KeyName"] for k in ec2.describe_key_pairs(Filters=flt)["KeyPairs"]],
    }


def down(*args: str) -> Any:
    return CliRunner().invoke(app, ["down", *args])


def fogiac(*args: str) -> Any:
    return CliRunner().invoke(app, list(args))


def test_up_records_what_it_made_and_a_second_up_changes_nothing(engine_is_harness: Harness, ec2: Any,
                                                                 tmp_path: Path) -> None:
    import json
    import stat

    from fogiac.plan.document import APPLIED_FILE

    path = write_manifest(tmp_path, "roundtrip", nodes=(("planner", "c5.large"),))
    assert fogiac("plan", str(path), "--out", str(tmp_path / "reviewed.json")).exit_code == 0
    result = fogiac("up", str(path), "--yes", "--infra-only", "--plan", str(tmp_path / "reviewed.json"))
    assert result.exit_code == 0, result.output
    folder = stack_dir("roundtrip-dev")
    outputs = json.loads((folder / OUTPUTS_FILE).read_text())
    instance = outputs["compute"]["hosts"]["planner"]["instance_id"]
    assert outputs["zone"] == "us-west-2a" and outputs["network"]["vpc_id"].startswith("vpc-")
    assert f"planner: {instance} c5.large" in result.stdout
    assert "Client VPN endpoint's subnet association takes about 10 minutes" in result.stderr
    assert stat.S_IMODE((folder / SSH_KEY_FILE).stat().st_mode) == 0o600
    assert _tagged(ec2, "roundtrip-dev")["instances"] == [instance]
    created = list(engine_is_harness.created)
    assert fogiac("plan", str(path), "--detailed-exitcode").exit_code == 0, "applied.json is the plan document"

    again = fogiac("up", str(path), "--yes", "--infra-only")
    assert again.exit_code == 0, again.output
    assert engine_is_harness.created == [] and sorted(engine_is_harness.reused) == sorted(created)
    assert json.loads((folder / OUTPUTS_FILE).read_text()) == outputs
    assert instance in fogiac("status", str(path)).stdout

    (folder / "known_hosts").write_text("203.0.113.9 ssh-ed25519 AAAAC3NzaC1lZDI1NTE5AAAA\n")  # as provisioning left it
    assert down(str(path), "--yes").exit_code == 0
    assert not (folder / APPLIED_FILE).exists() and not (folder / OUTPUTS_FILE).exists()
    assert not (folder / "known_hosts").exists()  # the addresses go back to AWS: forget their keys
    assert _tagged(ec2, "roundtrip-dev") == {"vpcs": [], "instances": [], "keys": []}


def test_down_after_a_failed_apply_leaves_nothing(engine_is_harness: Harness, ec2: Any, tmp_path: Path) -> None:
    path = write_manifest(tmp_path, "halfway", nodes=(("planner", "c5.large"),))
    plan = make_plan(tmp_path, "halfway", nodes=(("planner", "c5.large"),))
    engine_is_harness.fail_at = 25
    with pytest.raises(InjectedFailure):
        engine_is_harness.apply(plan, certs=new_bundle(plan.stack), operator_cidrs=("203.0.113.7/32",),
                                public_key_openssh=PUBLIC_KEY)
    orphan = ec2.create_security_group(  # made outside any state, as a crash between create and record would
        GroupName="orphan", Description="orphan", VpcId=_tagged(ec2, plan.stack)["vpcs"][0],
        TagSpecifications=[{"ResourceType": "security-group", "Tags": [{"Key": "fogiac:stack", "Value": plan.stack}]}])
    result = down(str(path), "--yes")
    assert result.exit_code == 0, result.output
    # the sweep removed the orphan the engine never knew, and down counts it
    assert result.stdout.splitlines()[-1] == f"halfway-dev: removed 1 (security-group {orphan['GroupId']}); nothing left"
    assert "could not delete" not in result.stderr
    gone = ec2.describe_security_groups(Filters=[{"Name": "group-id", "Values": [orphan["GroupId"]]}])
    assert gone["SecurityGroups"] == []
    assert _tagged(ec2, plan.stack) == {"vpcs": [], "instances": [], "keys": []}


def test_keep_network_removes_compute_and_says_what_the_network_costs(engine_is_harness: Harness, ec2: Any,
                                                                      tmp_path: Path) -> None:
    path = write_manifest(tmp_path, "kept")
    plan = make_plan(tmp_path, "kept")
    outputs = engine_is_harness.apply(plan, certs=new_bundle(plan.stack), operator_cidrs=("203.0.113.7/32",),
                                      public_key_openssh=PUBLIC_KEY)
    write_json_atomic(stack_dir(plan.stack) / OUTPUTS_FILE, {"zone": "us-west-2a", **outputs})
    deployment.finish(plan, path, plan_digest="applied")  # as up records it
    result = down(str(path), "--yes", "--keep-network")
    assert result.exit_code == 0, result.output
    assert "kept the network stack: $0.10/h while kept (Client VPN association; VPC, subnets and gateway are free)" \
        in result.stdout
    assert fogiac("status", str(path)).stdout.splitlines()[0] == (
        "kept-dev: network only (down --keep-network); `fogiac up` makes the compute again, `fogiac down` removes "
        "the network")
    left = _tagged(ec2, plan.stack)
    assert left["instances"] == [] and left["keys"] == [] and left["vpcs"] == [outputs["network"]["vpc_id"]]
    assert set(read_json(stack_dir(plan.stack) / OUTPUTS_FILE)) == {"zone", "network"}
    assert down(str(path), "--yes").exit_code == 0
    assert _tagged(ec2, plan.stack) == {"vpcs": [], "instances": [], "keys": []}
    assert not (stack_dir(plan.stack) / OUTPUTS_FILE).exists()


def test_down_exits_1_naming_what_it_could_not_delete(engine_is_harness: Harness, ec2: Any, acm: Any,
                                                      tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = write_manifest(tmp_path, "stuck")
    plan = make_plan(tmp_path, "stuck")
    engine_is_harness.apply(plan, certs=new_bundle(plan.stack), operator_cidrs=("203.0.113.7/32",),
                            public_key_openssh=PUBLIC_KEY)
    instance = _tagged(ec2, plan.stack)["instances"][0]
    ec2.modify_instance_attribute(InstanceId=instance, DisableApiTermination={"Value": True})
    result = down(str(path), "--yes")
    assert result.exit_code == 1
    assert f"could not delete: instance {instance}" in result.stderr.splitlines()
    assert result.stdout.splitlines()[-1].startswith("stuck-dev: ") and "left" in result.stdout.splitlines()[-1]
    ec2.modify_instance_attribute(InstanceId=instance, DisableApiTermination={"Value": False})
    assert down(str(path), "--yes").exit_code == 0
    assert _tagged(ec2, plan.stack) == {"vpcs": [], "instances": [], "keys": []}
    assert os.listdir(stack_dir(plan.stack)) == []


def test_up_without_an_edge_master_stops_before_anything_is_created(engine_is_harness: Harness, ec2: Any,
                                                                    tmp_path: Path) -> None:
    from fogiac.procs import free_port

    path = write_manifest(tmp_path, "noedge", nodes=(("planner", "c5.large"),))
    port = free_port()
    result = fogiac("up", str(path), "--yes", "--edge-master", f"http://127.0.0.1:{port}")
    assert result.exit_code == 1
    assert result.stderr.strip().splitlines()[-1] == (
        f"error: no ROS master answers at http://127.0.0.1:{port} (edge.ros_master); start roscore, "
        "or pass --start-edge-master to let fogiac run one")
    assert list(engine_is_harness.created) == []
    assert not stack_dir("noedge-dev", create=False).exists()


def test_plan_diffs_against_what_an_apply_recorded(engine_is_harness: Harness, ec2: Any, tmp_path: Path) -> None:
    """After an apply against LocalStack, plan shows only what an edit changes, per resource."""
    path = write_manifest(tmp_path, "diffed", nodes=(("planner", "c5.large"),))
    result = fogiac("up", str(path), "--yes", "--infra-only")
    assert result.exit_code == 0, result.output
    unchanged = fogiac("plan", str(path), "--detailed-exitcode")
    assert unchanged.exit_code == 0, unchanged.output
    assert "No changes." in unchanged.stdout

    path.write_text(path.read_text().replace("c5.large", "c5.xlarge"))
    changed = fogiac("plan", str(path), "--detailed-exitcode")
    assert changed.exit_code == 2, changed.output
    lines = changed.stdout.splitlines()
    assert "Plan: 0 to add, 1 to change, 0 to destroy." in lines
    assert any(line.strip().startswith("~ aws:ec2/instance:Instance diffed-dev-host-planner") for line in lines), lines
    assert "      instanceType: c5.large -> c5.xlarge" in lines  # changed in place, as AWS does (stop, modify, start)
    assert down(str(path), "--yes").exit_code == 0


def test_status_shows_a_failed_up_as_partial_until_down(engine_is_harness: Harness, ec2: Any,
                                                        tmp_path: Path) -> None:
    """AWS refuses the compute layer (a key pair of the stack's name is there already): the network
    exists, the deployment record says partial, and status says so, as on the local target."""
    path = write_manifest(tmp_path, "broken", nodes=(("planner", "c5.large"),))
    ec2.import_key_pair(KeyName="fogiac-broken-dev", PublicKeyMaterial=PUBLIC_KEY.encode())
    try:
        failed = fogiac("up", str(path), "--yes", "--infra-only")
        assert failed.exit_code == 1, failed.output
        assert "compute stack failed" in failed.stderr
        assert _tagged(ec2, "broken-dev")["vpcs"]  # the network was made before the refusal
        shown = fogiac("status", str(path))
        assert shown.exit_code == 0, shown.output
        assert shown.stdout.splitlines()[:2] == [
            "broken-dev: partial: the last up did not finish; `fogiac up` completes it, `fogiac down` removes "
            "what it made", "broken-dev: no instances"]
        assert json.loads(fogiac("status", str(path), "--json").stdout)["partial"] is True
    finally:
        ec2.delete_key_pair(KeyName="fogiac-broken-dev")
    assert down(str(path), "--yes").exit_code == 0
    after = fogiac("status", str(path))
    assert after.exit_code == 0 and "partial" not in after.stdout, after.output
    assert _tagged(ec2, "broken-dev") == {"vpcs": [], "instances": [], "keys": []}
