"""What the aws target feeds the one engine, checked without a Pulumi CLI: the project and region, the SSH
key, the ids its state knows (the engine's own workspace, naming and events: tests/pulumi_engine/).

The Pulumi CLI cannot be installed on these machines (shared/TESTING.md), so up/destroy through
the Automation API run only in users' CI (examples/ci/); a fake ``pulumi`` that only answers
``pulumi version`` stands in where the version check is under test.
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import pytest

from fogiac.pulumi_engine.workspace import PULUMI_CLI_VERSION, passphrase
from fogiac.state import stack_dir
from fogiac.targets.aws import engine
from fogiac.targets.aws.errors import EngineError
from tests.support.pulumi import fake_pulumi, no_pulumi

__all__ = ["no_pulumi"]  # a fixture the tests below ask for


def test_engine_without_cli_touches_no_state(no_pulumi: None, tmp_path: Path) -> None:
    from fogiac.manifest.schema import load_manifest
    from fogiac.plan.compile import compile_plan

    plan = compile_plan(load_manifest(Path(__file__).parents[3] / "examples" / "minimal.yaml"))
    with pytest.raises(EngineError, match=r"^the Pulumi CLI is not installed"):
        engine.Engine(plan)
    assert not stack_dir(plan.stack, create=False).exists()


def test_ssh_key_is_made_once_private_half_0600() -> None:
    public = engine.ssh_public_key("k-dev")
    assert public.startswith("ssh-ed25519 ")
    private = stack_dir("k-dev") / engine.SSH_KEY_FILE
    assert stat.S_IMODE(private.stat().st_mode) == 0o600
    assert b"OPENSSH PRIVATE KEY" in private.read_bytes()
    assert engine.ssh_public_key("k-dev") == public


def test_known_ids_come_from_outputs_and_checkpoints() -> None:
    folder = stack_dir("ids-dev")
    (folder / engine.OUTPUTS_FILE).write_text(json.dumps(
        {"network": {"vpc_id": "vpc-1"}, "compute": {"hosts": {"a": {"instance_id": "i-1"}}}}))
    checkpoint = folder / "pulumi" / ".pulumi" / "stacks" / "fogiac" / "ids-dev-network.json"
    checkpoint.parent.mkdir(parents=True)
    checkpoint.write_text(json.dumps({"checkpoint": {"latest": {"resources": [{"id": "subnet-9"}, {"id": "sg-3"}]}}}))
    assert engine.known_ids("ids-dev") == {"vpc-1", "i-1", "subnet-9", "sg-3"}
    assert engine.known_ids("nothing-dev") == frozenset()


def test_no_boto3_or_pulumi_on_import() -> None:
    import subprocess
    import sys

    code = ("import sys, fogiac.targets, fogiac.targets.aws.engine, fogiac.targets.aws.api, fogiac.targets.aws.sweep, fogiac.cli.deploy, fogiac.plan.saved;"
            "print(sorted(m for m in ('boto3', 'pulumi', 'pulumi.automation') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={**os.environ, "PYTHONPATH": str(Path(__file__).parents[3])})
    assert out.stdout.strip() == "[]"


def test_workspace_options_for_the_automation_api(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from fogiac.manifest.schema import load_manifest
    from fogiac.plan.compile import compile_plan

    monkeypatch.setenv("PATH", str(tmp_path / "bin"))
    fake_pulumi(tmp_path / "bin", f"v{PULUMI_CLI_VERSION}")
    monkeypatch.delenv("PULUMI_CONFIG_PASSPHRASE", raising=False)
    monkeypatch.delenv("PULUMI_CONFIG_PASSPHRASE_FILE", raising=False)
    plan = compile_plan(load_manifest(Path(__file__).parents[3] / "examples" / "minimal.yaml"))
    opts = engine.Engine(plan).engine._options()
    backend = (stack_dir(plan.stack) / "pulumi").as_uri()
    assert opts.secrets_provider == "passphrase"
    assert opts.project_settings.name == engine.PROJECT and opts.project_settings.backend.url == backend
    assert opts.env_vars["PULUMI_BACKEND_URL"] == backend
    assert opts.env_vars["PULUMI_CONFIG_PASSPHRASE"] == passphrase(plan.stack)
    assert engine.stack_config(plan) == {"aws:region": "us-west-2"}


def test_destroy_and_refresh_of_a_never_applied_stack_write_nothing(tmp_path: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    from fogiac.manifest.schema import load_manifest
    from fogiac.plan.compile import compile_plan

    monkeypatch.setenv("PATH", str(tmp_path / "bin"))
    fake_pulumi(tmp_path / "bin", f"v{PULUMI_CLI_VERSION}")
    plan = compile_plan(load_manifest(Path(__file__).parents[3] / "examples" / "minimal.yaml"))
    assert engine.Engine(plan).destroy() == []
    assert engine.Engine(plan).refresh() == []
    assert not stack_dir(plan.stack, create=False).exists()
