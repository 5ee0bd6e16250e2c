"""The plain-``pulumi preview`` entry: stack config, state-dir keys, both layers end to end."""

from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pulumi
import pytest

from fogiac.errors import PlanError
from fogiac.certs import load_or_create_ssh_key
from stacks.aws.entry import StackConfig, main, operator_cidrs, read_config

from .conftest import EXAMPLES, compiled
from .recorder import Recorder

STACKS = Path(__file__).resolve().parents[2] / "stacks" / "aws"  # the aws programs, where plain pulumi runs


class _Config:
    """Stack config as ``pulumi config set`` would give it to the program."""

    def update(self, values: dict[str, str]) -> None:
        for key, value in values.items():
            pulumi.runtime.set_config(key, value)


@pytest.fixture
def config() -> Iterator[_Config]:
    pulumi.runtime.set_all_config({})
    yield _Config()
    pulumi.runtime.set_all_config({})


def test_read_config_defaults_and_paths(tmp_path: Path) -> None:
    got = read_config({"manifest": "../m.yaml", "sshFrom": " 192.0.2.1/32, 198.51.100.0/24"}.get, base=tmp_path)
    assert got == StackConfig(
        manifest=(tmp_path.parent / "m.yaml").resolve(),
        layer="network",
        environment="dev",
        target="aws",
        ssh_from=("192.0.2.1/32", "198.51.100.0/24"),
        network_stack=None,
    )


def test_read_config_errors(tmp_path: Path) -> None:
    with pytest.raises(PlanError, match="^stack config fogiac:manifest is not set; run: pulumi config set"):
        read_config({}.get, base=tmp_path)
    with pytest.raises(PlanError, match=r"^fogiac:layer is 'storage'; valid: network, compute$"):
        read_config({"manifest": "m.yaml", "layer": "storage"}.get, base=tmp_path)


def test_auto_ssh_from_needs_the_operator_address(tmp_path: Path) -> None:
    plan = compiled(EXAMPLES / "minimal.yaml")
    config = read_config({"manifest": "m.yaml"}.get, base=tmp_path)
    with pytest.raises(PlanError, match="ssh_from is auto; set your address: pulumi config set fogiac:sshFrom"):
        operator_cidrs(plan, config)


def test_ssh_key_is_made_once_with_a_private_file(tmp_path: Path) -> None:
    public = load_or_create_ssh_key(tmp_path / "ssh")
    assert public.startswith("ssh-ed25519 ") and public.endswith(" fogiac")
    assert stat.S_IMODE(os.stat(tmp_path / "ssh" / "id_ed25519").st_mode) == 0o600
    assert b"OPENSSH PRIVATE KEY" in (tmp_path / "ssh" / "id_ed25519").read_bytes()
    assert load_or_create_ssh_key(tmp_path / "ssh") == public


def test_network_then_compute_layer(config: _Config, _state_dir: Path) -> None:
    config.update({"fogiac:manifest": str(EXAMPLES / "minimal.yaml"), "fogiac:sshFrom": "192.0.2.7/32"})
    network = Recorder()
    exports = network.run(lambda: main(base=Path.cwd()), stack="minimal-dev-network")
    assert exports["vpn_endpoint_id"] == "id-minimal-dev-endpoint"
    assert network.inputs["minimal-dev-hosts-in-tcp-22-192.0.2.7-32"]["cidrIpv4"] == "192.0.2.7/32"
    assert sorted(p.name for p in (_state_dir / "minimal-dev" / "certs").iterdir()) == [
        "ca.key", "ca.pem", "client.key", "client.pem", "vpn.key", "vpn.pem"
    ]  # no host's key: each host makes its own

    config.update({"fogiac:layer": "compute", "fogiac:networkStack": "minimal-dev-network"})
    compute = Recorder()
    compute.stack_outputs = exports
    hosts = compute.run(lambda: main(base=Path.cwd()), stack="minimal-dev-compute")["hosts"]
    assert compute.types["minimal-dev-network"] == "pulumi:pulumi:StackReference"
    assert compute.inputs["minimal-dev-host-talker"]["subnetId"] == "id-minimal-dev-subnet-hosts"
    assert compute.inputs["minimal-dev-host-talker"]["vpcSecurityGroupIds"] == ["id-minimal-dev-sg-hosts"]
    key = (_state_dir / "minimal-dev" / "ssh" / "id_ed25519.pub").read_text().strip()
    assert compute.inputs["minimal-dev-key"]["publicKey"] == key
    assert hosts["talker"]["instance_id"] == "id-minimal-dev-host-talker"


def test_compute_layer_needs_the_network_stack(config: _Config) -> None:
    config.update({"fogiac:manifest": str(EXAMPLES / "minimal.yaml"), "fogiac:layer": "compute"})
    with pytest.raises(PlanError, match=r"^the compute layer needs fogiac:networkStack"):
        Recorder().run(lambda: main(base=Path.cwd()))


def test_region_mismatch_is_refused(config: _Config) -> None:
    config.update({"fogiac:manifest": str(EXAMPLES / "minimal.yaml"), "aws:region": "eu-west-1"})
    with pytest.raises(PlanError, match=r"^aws:region is eu-west-1 but the manifest says us-west-2"):
        Recorder().run(lambda: main(base=Path.cwd()))


_RUN_MAIN = """
import json, runpy, sys
import pulumi
from fogiac.pulumi_engine.offline import run_program

class M(pulumi.runtime.Mocks):
    def new_resource(self, args):
        return "id-" + args.name, dict(args.inputs, dnsName="vpn.example")
    def call(self, args):
        return {}

out = run_program(lambda: runpy.run_path("__main__.py", run_name="__main__"), mocks=M(),
                  project="fogiac", stack="minimal-dev", preview=True)
print(json.dumps(out))
"""


def test_main_runs_like_pulumi_runs_it(_state_dir: Path) -> None:
    """A fresh interpreter in stacks/aws/ (as the Pulumi language host starts it), config from env."""
    env = dict(os.environ)
    env["PULUMI_CONFIG"] = json.dumps({"fogiac:manifest": "../../examples/minimal.yaml",
                                       "fogiac:sshFrom": "192.0.2.7/32"})
    done = subprocess.run(
        [sys.executable, "-c", _RUN_MAIN], cwd=STACKS, env=env, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["vpc_id"] == "id-minimal-dev-vpc"
    assert out["vpn_dns_name"] == "vpn.example"
