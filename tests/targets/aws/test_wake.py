"""A host autostop stopped comes back with the next `fogiac up`: started, not recreated (LocalStack).

The harness stands in for the Pulumi engine (see test_deploy.py); starting the stopped instance
is fogiac's own boto3 call, before the engine runs, so the engine's refresh finds the same
instance running and nothing to replace.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.state import stack_dir
from fogiac.targets.aws.engine import OUTPUTS_FILE
from fogiac.targets.aws.target import HOST_KEYS_FILE, pinned_host_keys

from .harness import Harness
from .plans import write_manifest
from .test_deploy import _tagged, engine_is_harness  # noqa: F401 (a fixture)

pytestmark = pytest.mark.localstack


def fogiac(*args: str) -> Any:
    return CliRunner().invoke(app, list(args))


def _state(ec2: Any, instance: str) -> str:
    return str(ec2.describe_instances(InstanceIds=[instance])["Reservations"][0]["Instances"][0]["State"]["Name"])


def test_up_starts_a_stopped_host_again_same_instance(engine_is_harness: Harness, ec2: Any,  # noqa: F811
                                                      tmp_path: Path) -> None:
    path = write_manifest(tmp_path, "waking", nodes=(("planner", "c5.large"),))
    first = fogiac("up", str(path), "--yes", "--infra-only")
    assert first.exit_code == 0, first.output
    assert first.stdout.splitlines()[-1] == ("cost: $0.2350/h while up; autostop stops the hosts after 30m 00s "
                                             "without an edge; the Client VPN association is billed until "
                                             "`fogiac down`")
    outputs = json.loads((stack_dir("waking-dev") / OUTPUTS_FILE).read_text())
    instance = outputs["compute"]["hosts"]["planner"]["instance_id"]
    created = list(engine_is_harness.created)
    behaviour = ec2.describe_instance_attribute(InstanceId=instance, Attribute="instanceInitiatedShutdownBehavior")
    assert behaviour["InstanceInitiatedShutdownBehavior"]["Value"] == "stop"  # the watchdog's poweroff stops it

    ec2.stop_instances(InstanceIds=[instance])  # as the watchdog's poweroff would
    ec2.get_waiter("instance_stopped").wait(InstanceIds=[instance], WaiterConfig={"Delay": 1, "MaxAttempts": 30})
    doc = json.loads(fogiac("status", str(path), "--json").stdout)
    host = doc["hosts"][0]
    assert (host["instance_id"], host["state"]) == (instance, "stopped")
    assert host["stopped_at"] is not None and host["stopped_by"] == "a user", host  # the test stopped it, not autostop
    assert doc["cost"]["lines"][0] == {"item": "instance planner (c5.large, stopped)", "usd_per_hour": 0.0,
                                       "running": False, "spot_estimate": False, "since": None, "cost_usd": None,
                                       "price_unknown": False}
    assert [line["item"] for line in doc["cost"]["lines"]][1:] == ["Client VPN subnet association"]
    assert doc["cost"]["usd_per_hour"] == 0.1  # the network stack is still billed while the host sleeps

    again = fogiac("up", str(path), "--yes", "--infra-only")
    assert again.exit_code == 0, again.output
    assert f"started {instance} again (stopped while idle): the same instances, nothing recreated" in again.stderr
    assert _state(ec2, instance) == "running"
    assert _tagged(ec2, "waking-dev")["instances"] == [instance]
    assert engine_is_harness.created == [] and sorted(engine_is_harness.reused) == sorted(created)
    assert json.loads((stack_dir("waking-dev") / OUTPUTS_FILE).read_text()) == outputs  # network_since kept

    running = json.loads(fogiac("status", str(path), "--json").stdout)
    assert running["hosts"][0]["state"] == "running" and running["hosts"][0]["stopped_at"] is None
    assert running["cost"]["usd_per_hour"] == pytest.approx(0.085 + 0.1)
    assert fogiac("down", str(path), "--yes").exit_code == 0
    assert _tagged(ec2, "waking-dev") == {"vpcs": [], "instances": [], "keys": []}


def test_up_leaves_a_running_stack_alone(engine_is_harness: Harness, ec2: Any, tmp_path: Path) -> None:  # noqa: F811
    path = write_manifest(tmp_path, "awake", nodes=(("planner", "c5.large"),))
    assert fogiac("up", str(path), "--yes", "--infra-only").exit_code == 0
    again = fogiac("up", str(path), "--yes", "--infra-only")
    assert again.exit_code == 0 and "started" not in again.stderr
    assert fogiac("down", str(path), "--yes").exit_code == 0


def test_host_keys_are_read_from_the_console_once_per_instance(tmp_path: Path) -> None:
    """cloud-init prints them on the first boot only: a restarted instance is known by the keys pinned then."""
    asked: list[str] = []

    def console() -> tuple[str, ...]:
        asked.append("console")
        return ("SHA256:abc",)

    assert pinned_host_keys("keys-dev", "i-1", fetch=console) == ("SHA256:abc",)
    assert pinned_host_keys("keys-dev", "i-1", fetch=lambda: pytest.fail("read the console twice")) == ("SHA256:abc",)
    assert pinned_host_keys("keys-dev", "i-2", fetch=console) == ("SHA256:abc",)
    assert asked == ["console", "console"]
    assert set(json.loads((stack_dir("keys-dev") / HOST_KEYS_FILE).read_text())) == {"i-1", "i-2"}
