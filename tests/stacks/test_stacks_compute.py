"""Compute: key pair, AMI lookups, hardened instances and their user data."""

from __future__ import annotations

import pytest

from fogiac.targets.aws.placement import NVIDIA, UBUNTU
from fogiac.targets.aws.offline import OfflinePlan, offline_public_key
from stacks.aws.compute import HOST_KEYS_BEGIN, HOST_KEYS_END
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.targets.aws.offline import declare
from stacks.aws.program import compute_program

from .conftest import EXAMPLES
from .recorder import Recorder

INSTANCE = "aws:ec2/instance:Instance"


def instances(plan: OfflinePlan) -> dict[str, dict]:
    return {r.name: r.inputs for r in plan.of_type(INSTANCE)}


@pytest.mark.parametrize("key", ["minimal", "proxy", "gpu"])
def test_instances_are_hardened(offline: dict[str, OfflinePlan], key: str) -> None:
    plan = offline[key]
    hosts = {f"{plan.plan.stack}-host-{h.name}": h for h in plan.plan.hosts}
    declared = instances(plan)
    assert set(declared) == set(hosts)
    for name, inputs in declared.items():
        host = hosts[name]
        assert inputs["instanceType"] == host.machine
        assert inputs["metadataOptions"]["httpTokens"] == "required"
        assert inputs["rootBlockDevice"] == {
            "volumeType": "gp3", "encrypted": True, "volumeSize": host.disk_gb, "deleteOnTermination": True
        }
        assert inputs["associatePublicIpAddress"] is True
        assert inputs["ebsOptimized"] is True
        assert inputs["subnetId"] == f"<{plan.plan.stack}-subnet-hosts.id>"
        assert inputs["vpcSecurityGroupIds"] == (f"<{plan.plan.stack}-sg-hosts.id>",)
        assert inputs["keyName"] == f"fogiac-{plan.plan.stack}"
        assert inputs["tags"]["Name"] == f"{plan.plan.stack}-{host.name}"


def test_spot_only_when_asked(offline: dict[str, OfflinePlan]) -> None:
    (planner,) = instances(offline["proxy"]).values()
    assert planner["instanceMarketOptions"]["marketType"] == "spot"
    assert planner["rootBlockDevice"]["volumeSize"] == 50
    assert all("instanceMarketOptions" not in i for i in instances(offline["gpu"]).values())


def test_gpu_types_use_the_nvidia_image(offline: dict[str, OfflinePlan]) -> None:
    declared = instances(offline["gpu"])
    assert NVIDIA.name_pattern in declared["grasp-dev-host-dexnet"]["ami"]
    assert UBUNTU.name_pattern in declared["grasp-dev-host-helper"]["ami"]
    assert "docker.io" not in declared["grasp-dev-host-dexnet"]["userData"]
    assert "nvidia-ctk runtime configure" in declared["grasp-dev-host-dexnet"]["userData"]
    assert "docker.io" in declared["grasp-dev-host-helper"]["userData"]


def test_user_data_installs_docker_and_prints_host_keys(offline: dict[str, OfflinePlan]) -> None:
    (user_data,) = (i["userData"] for i in instances(offline["minimal"]).values())
    assert user_data.startswith("#cloud-config\n")
    assert "  - docker.io\n" in user_data
    assert HOST_KEYS_BEGIN in user_data and HOST_KEYS_END in user_data
    assert "ssh-keygen -l -E sha256" in user_data
    assert "FOGIAC_HOST=talker" in user_data


def test_one_ami_lookup_per_distinct_image(offline: dict[str, OfflinePlan]) -> None:
    plan = offline["gpu"].plan
    recorder = Recorder()
    network = {"subnet_ids": {"hosts": "subnet-1"}, "security_group_ids": {"hosts": "sg-1"}}
    exports = recorder.run(
        lambda: compute_program(plan, network=network, public_key_openssh="ssh-ed25519 AAAAtest fogiac"),
        stack=plan.stack,
    )
    lookups = [args for token, args in recorder.calls if token == "aws:ec2/getAmi:getAmi"]
    assert len(lookups) == 2
    by_owner = {tuple(a["owners"]): a for a in lookups}
    assert by_owner[UBUNTU.owners]["mostRecent"] is True
    assert {"name": "name", "values": [NVIDIA.name_pattern]} in by_owner[NVIDIA.owners]["filters"]
    assert recorder.inputs["grasp-dev-key"]["publicKey"] == "ssh-ed25519 AAAAtest fogiac"
    assert recorder.inputs["grasp-dev-host-dexnet"]["subnetId"] == "subnet-1"
    assert recorder.inputs["grasp-dev-host-dexnet"]["ami"].startswith("ami-")
    assert exports["hosts"]["dexnet"] == {
        "instance_id": "id-grasp-dev-host-dexnet",
        "public_ip": "203.0.113.10",
        "private_ip": "10.10.0.10",
        "machine": "g4dn.xlarge",
    }


def test_offline_key_pair_is_a_placeholder(offline: dict[str, OfflinePlan]) -> None:
    (key,) = offline["minimal"].of_type("aws:ec2/keyPair:KeyPair")
    assert key.inputs["publicKey"] == offline_public_key("minimal-dev")
    assert offline["minimal"].outputs["compute"]["hosts"]["talker"]["machine"] == "t3.small"


def test_autostop_sets_what_a_poweroff_does(offline: dict[str, OfflinePlan], tmp_path) -> None:
    """Default on aws: stop; terminate when asked; a one-time spot instance cannot stop, so it terminates."""
    assert [i["instanceInitiatedShutdownBehavior"] for i in instances(offline["minimal"]).values()] == ["stop"]
    assert {i["instanceInitiatedShutdownBehavior"] for i in instances(offline["gpu"]).values()} == {"terminate"}
    assert [i["instanceInitiatedShutdownBehavior"] for i in instances(offline["proxy"]).values()] == ["terminate"]
    off = tmp_path / "off.yaml"
    off.write_text((EXAMPLES / "minimal.yaml").read_text().replace("  region: us-west-2\n",
                                                                  "  region: us-west-2\n  autostop: \"off\"\n"))
    plan = compile_plan(load_manifest(off))
    assert plan.autostop is None
    assert all("instanceInitiatedShutdownBehavior" not in i for i in instances(declare(plan)).values())
