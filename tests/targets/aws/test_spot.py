"""Spot with fallback against LocalStack: the harness refuses spot launches as AWS does with no capacity.

fogiac then makes the host on-demand, says so, keeps it on-demand on later ups (switching market
would replace it) and leaves no instance and no spot request after down. What the stack costs
(``up``'s last line, ``status``'s cost guard) follows what EC2 gave: a spot instance at the
catalogue's spot estimate, labelled with its date, a fallen-back one at on-demand. LocalStack records a
spot launch as an instance with lifecycle "spot" and makes no spot request object, so "no stray
request" is checked as far as the emulator can show it.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.targets.aws.catalog import catalog, spot_price
from fogiac.state import stack_dir
from fogiac.targets.aws.engine import OUTPUTS_FILE
from fogiac.targets.aws.spot import ON_DEMAND, no_capacity

from .harness import Harness
from .plans import manifest_text
from .test_deploy import _tagged, engine_is_harness  # noqa: F401 (a fixture)

pytestmark = pytest.mark.localstack


def fogiac(*args: str) -> Any:
    return CliRunner().invoke(app, list(args))


def _spot_manifest(tmp_path: Path, name: str) -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(manifest_text(name, nodes=(("planner", "c5.large"),)) + "    spot: true\n")
    return path


def _instance(ec2: Any, stack: str) -> dict[str, Any]:
    [found] = [i for r in ec2.describe_instances(Filters=[
        {"Name": "tag:fogiac:stack", "Values": [stack]},
        {"Name": "instance-state-name", "Values": ["pending", "running"]}])["Reservations"] for i in r["Instances"]]
    return dict(found)


def _no_stray_spot_request(ec2: Any, instances: list[str]) -> None:
    requests = ec2.describe_spot_instance_requests(Filters=[{"Name": "instance-id", "Values": instances}])
    assert [r for r in requests["SpotInstanceRequests"] if r["State"] in {"open", "active"}] == []


def test_no_spot_capacity_falls_back_to_on_demand_and_says_so(engine_is_harness: Harness, ec2: Any,  # noqa: F811
                                                              tmp_path: Path) -> None:
    path = _spot_manifest(tmp_path, "nospot")
    engine_is_harness.spot_capacity = False
    result = fogiac("up", str(path), "--yes", "--infra-only")
    assert result.exit_code == 0, result.output
    assert ("planner: no spot capacity for c5.large in us-west-2a (InsufficientInstanceCapacity); "
            "running on-demand instead at $0.0850/h") in result.stderr
    instance = _instance(ec2, "nospot-dev")
    assert instance.get("InstanceLifecycle") != "spot"
    [key] = [k for k in engine_is_harness.state if k.endswith("host-planner")]
    assert engine_is_harness.state[key]["inputs"]["instanceInitiatedShutdownBehavior"] == "stop"  # on-demand can stop
    behaviour = ec2.describe_instance_attribute(InstanceId=instance["InstanceId"],
                                                Attribute="instanceInitiatedShutdownBehavior")
    assert behaviour["InstanceInitiatedShutdownBehavior"]["Value"] == "stop"
    assert json.loads((stack_dir("nospot-dev") / OUTPUTS_FILE).read_text())[ON_DEMAND] == ["planner"]
    # priced as what it runs as: on-demand, though the manifest asked for spot
    assert result.stdout.splitlines()[-1].startswith("cost: $0.2350/h while up; autostop stops the hosts")
    status = json.loads(fogiac("status", str(path), "--json").stdout)
    assert [(h["host"], h["market"]) for h in status["hosts"]] == [("planner", "on-demand")]
    line = status["cost"]["lines"][0]
    assert (line["item"], line["usd_per_hour"], line["spot_estimate"]) == ("instance planner (c5.large, running)",
                                                                           0.085, False)
    assert status["cost"]["spot_estimate_as_of"] is None and status["cost"]["usd_per_hour"] == 0.185

    engine_is_harness.spot_capacity = True  # capacity came back: the running on-demand host is kept, not replaced
    again = fogiac("up", str(path), "--yes", "--infra-only")
    assert again.exit_code == 0, again.output
    assert engine_is_harness.created == [] and _instance(ec2, "nospot-dev")["InstanceId"] == instance["InstanceId"]
    assert again.stdout.splitlines()[-1].startswith("cost: $0.2350/h while up;")  # still on-demand, still priced so

    assert fogiac("down", str(path), "--yes").exit_code == 0
    assert _tagged(ec2, "nospot-dev") == {"vpcs": [], "instances": [], "keys": []}
    _no_stray_spot_request(ec2, [instance["InstanceId"]])
    assert not (stack_dir("nospot-dev") / OUTPUTS_FILE).exists()  # the fallback is forgotten with the stack


def test_spot_when_there_is_capacity(engine_is_harness: Harness, ec2: Any, tmp_path: Path) -> None:  # noqa: F811
    path = _spot_manifest(tmp_path, "gotspot")
    result = fogiac("up", str(path), "--yes", "--infra-only")
    assert result.exit_code == 0, result.output
    assert "no spot capacity" not in result.stderr
    instance = _instance(ec2, "gotspot-dev")
    assert instance["InstanceLifecycle"] == "spot"
    behaviour = ec2.describe_instance_attribute(InstanceId=instance["InstanceId"],
                                                Attribute="instanceInitiatedShutdownBehavior")
    assert behaviour["InstanceInitiatedShutdownBehavior"]["Value"] == "terminate"  # one-time spot cannot stop
    assert ON_DEMAND not in json.loads((stack_dir("gotspot-dev") / OUTPUTS_FILE).read_text())
    spot = spot_price("c5.large", "us-west-2")
    assert spot is not None and spot < 0.085
    assert result.stdout.splitlines()[-1].startswith(
        f"cost: about ${spot + 0.15:.4f}/h while up (spot hosts at the catalogue's spot estimate of "
        f"{catalog().spot_as_of}; $0.2350/h at on-demand prices, the most spot costs); autostop")
    status = fogiac("status", str(path))
    assert "c5.large (spot)" in status.stdout
    text = " ".join(status.stdout.split())
    assert (f"(on-demand catalogue prices, spot instances at the catalogue's spot estimate of "
            f"{catalog().spot_as_of}; stopped hosts' disks not counted)") in text
    assert f"${spot:.4f}/h" in text and "instance planner (c5.large, spot, running) (spot estimate)" in text
    doc = json.loads(fogiac("status", str(path), "--json").stdout)["cost"]
    assert (doc["lines"][0]["usd_per_hour"], doc["lines"][0]["spot_estimate"]) == (spot, True)
    assert doc["usd_per_hour"] == round(spot + 0.1, 4) and doc["spot_estimate_as_of"] == catalog().spot_as_of
    assert fogiac("down", str(path), "--yes").exit_code == 0
    assert _tagged(ec2, "gotspot-dev") == {"vpcs": [], "instances": [], "keys": []}
    _no_stray_spot_request(ec2, [instance["InstanceId"]])


def test_other_engine_errors_are_not_taken_for_missing_capacity() -> None:
    assert no_capacity("compute stack failed: creating EC2 Instance: InsufficientInstanceCapacity: no") == \
        "InsufficientInstanceCapacity"
    assert no_capacity("compute stack failed: Spot request status: capacity-not-available") == "capacity-not-available"
    assert no_capacity("compute stack failed: UnauthorizedOperation: not allowed") == ""
