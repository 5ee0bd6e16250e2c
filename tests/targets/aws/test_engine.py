"""The engine's logic that needs no Pulumi CLI: naming, passphrase, backend, CLI pin, ids, timers.

The Pulumi CLI cannot be installed on these machines (shared/TESTING.md), so up/destroy through
the Automation API run only in users' CI (examples/ci/); a fake ``pulumi`` that only answers
``pulumi version`` stands in where the version check is under test.
"""

from __future__ import annotations

import json
import os
import stat
from importlib.metadata import version
from pathlib import Path

import pytest
from pulumi.automation import events

from fogiac.state import stack_dir
from fogiac.targets.aws import engine
from fogiac.targets.aws.errors import EngineError


def fake_pulumi(folder: Path, answer: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    script = folder / "pulumi"
    script.write_text(f"#!/bin/sh\necho {answer}\n")
    script.chmod(0o755)
    return script


@pytest.fixture
def no_pulumi(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PATH", str(tmp_path / "empty-bin"))
    monkeypatch.setenv("HOME", str(tmp_path / "home"))


def test_layers_are_named_per_manifest_environment_and_layer() -> None:
    assert engine.layer_stack("minimal-dev", "network") == "minimal-dev-network"
    assert engine.layer_stack("minimal-prod", "compute") == "minimal-prod-compute"
    with pytest.raises(EngineError, match=r"^unknown layer 'vpn'; valid: network, compute$"):
        engine.layer_stack("minimal-dev", "vpn")


def test_pin_matches_the_installed_sdk() -> None:
    major, minor, _ = engine.PULUMI_CLI_VERSION.split(".")
    assert version("pulumi").split(".")[:2] == [major, minor]
    assert engine.INSTALL.endswith(f"--version {engine.PULUMI_CLI_VERSION}")


def test_missing_cli_is_one_line_with_the_install_command(no_pulumi: None) -> None:
    with pytest.raises(EngineError, match=r"^the Pulumi CLI is not installed \(fogiac needs 3\.\d+\.\d+\); install it "
                                          r"with: curl -fsSL https://get\.pulumi\.com \| sh -s -- --version 3\.\d+\.\d+$"):
        engine.pulumi_cli()


def test_old_cli_is_refused_and_the_pinned_one_accepted(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PATH", str(tmp_path / "bin"))
    fake_pulumi(tmp_path / "bin", "v3.100.0")
    with pytest.raises(EngineError, match=r"is 3\.100\.0, fogiac needs 3\.\d+\.\d+ or a later 3\.x; install it with"):
        engine.pulumi_cli()
    fake_pulumi(tmp_path / "bin", f"v{engine.PULUMI_CLI_VERSION}")
    assert engine.pulumi_cli() == tmp_path / "bin" / "pulumi"


def test_engine_without_cli_touches_no_state(no_pulumi: None, tmp_path: Path) -> None:
    from fogiac.manifest.schema import load_manifest
    from fogiac.plan.compile import compile_plan

    plan = compile_plan(load_manifest(Path(__file__).parents[3] / "examples" / "minimal.yaml"))
    with pytest.raises(EngineError, match=r"^the Pulumi CLI is not installed"):
        engine.Engine(plan)
    assert not stack_dir(plan.stack, create=False).exists()


def test_generated_passphrase_is_0600_and_stable(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("PULUMI_CONFIG_PASSPHRASE", raising=False)
    monkeypatch.delenv("PULUMI_CONFIG_PASSPHRASE_FILE", raising=False)
    first = engine.passphrase("p-dev")
    path = stack_dir("p-dev") / engine.PASSPHRASE_FILE
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert len(first) >= 32 and engine.passphrase("p-dev") == first


def test_passphrase_from_the_environment_wins(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PULUMI_CONFIG_PASSPHRASE", "from-env")
    assert engine.passphrase("q-dev") == "from-env"
    assert not (stack_dir("q-dev") / engine.PASSPHRASE_FILE).exists()
    monkeypatch.delenv("PULUMI_CONFIG_PASSPHRASE")
    (tmp_path / "pp").write_text("from-file\n")
    monkeypatch.setenv("PULUMI_CONFIG_PASSPHRASE_FILE", str(tmp_path / "pp"))
    assert engine.passphrase("q-dev") == "from-file"


def test_workspace_uses_a_private_file_backend(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PULUMI_CONFIG_PASSPHRASE", "x")
    env = engine.workspace_env("w-dev")
    backend = stack_dir("w-dev") / "pulumi"
    assert env["PULUMI_BACKEND_URL"] == backend.as_uri() and env["PULUMI_BACKEND_URL"].startswith("file:///")
    assert stat.S_IMODE(backend.stat().st_mode) == 0o700
    assert env["PULUMI_CONFIG_PASSPHRASE"] == "x"


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


def _step(op: str, urn: str, typ: str) -> events.StepEventMetadata:
    return events.StepEventMetadata(op=events.OpType(op), urn=urn, type=typ, provider="")


def test_timers_follow_engine_events() -> None:
    now = [100.0]
    timers = engine.Timers(clock=lambda: now[0])
    vpc = "urn:pulumi:s::fogiac::fogiac:aws:Network$aws:ec2/vpc:Vpc::m-dev-vpc"
    sub = "urn:pulumi:s::fogiac::fogiac:aws:Network$aws:ec2/subnet:Subnet::m-dev-subnet-hosts"
    feed = [
        events.EngineEvent(1, 0, resource_pre_event=events.ResourcePreEvent(
            _step("create", "urn:pulumi:s::fogiac::pulumi:pulumi:Stack::fogiac-s", "pulumi:pulumi:Stack"))),
        events.EngineEvent(2, 0, resource_pre_event=events.ResourcePreEvent(_step("create", vpc, "aws:ec2/vpc:Vpc"))),
        events.EngineEvent(3, 0, resource_pre_event=events.ResourcePreEvent(_step("same", sub, "aws:ec2/subnet:Subnet"))),
    ]
    for event in feed:
        timers(event)
    assert list(timers.rows) == [vpc]
    assert [r.name for r in timers.running()] == ["m-dev-vpc"]
    now[0] = 103.5
    assert timers.rows[vpc].elapsed(now[0]) == 3.5
    timers(events.EngineEvent(4, 0, res_outputs_event=events.ResOutputsEvent(_step("create", vpc, "aws:ec2/vpc:Vpc"))))
    now[0] = 200.0
    assert timers.rows[vpc].elapsed(now[0]) == 3.5 and timers.running() == []
    inst = "urn:pulumi:s::fogiac::aws:ec2/instance:Instance::m-dev-host-a"
    timers(events.EngineEvent(5, 0, resource_pre_event=events.ResourcePreEvent(
        _step("create", inst, "aws:ec2/instance:Instance"))))
    timers(events.EngineEvent(6, 0, res_op_failed_event=events.ResOpFailedEvent(
        _step("create", inst, "aws:ec2/instance:Instance"), status=1, steps=1)))
    timers(events.EngineEvent(7, 0, diagnostic_event=events.DiagnosticEvent(
        message="creating instance: InsufficientInstanceCapacity\n", color="never", severity="error")))
    assert timers.rows[inst].failed
    assert timers.diagnostics == ["creating instance: InsufficientInstanceCapacity"]


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
    fake_pulumi(tmp_path / "bin", f"v{engine.PULUMI_CLI_VERSION}")
    monkeypatch.delenv("PULUMI_CONFIG_PASSPHRASE", raising=False)
    monkeypatch.delenv("PULUMI_CONFIG_PASSPHRASE_FILE", raising=False)
    plan = compile_plan(load_manifest(Path(__file__).parents[3] / "examples" / "minimal.yaml"))
    opts = engine.Engine(plan)._options()
    backend = (stack_dir(plan.stack) / "pulumi").as_uri()
    assert opts.secrets_provider == "passphrase"
    assert opts.project_settings.name == engine.PROJECT and opts.project_settings.backend.url == backend
    assert opts.env_vars["PULUMI_BACKEND_URL"] == backend
    assert opts.env_vars["PULUMI_CONFIG_PASSPHRASE"] == engine.passphrase(plan.stack)
    assert engine.stack_config(plan) == {"aws:region": "us-west-2"}


def test_engine_failures_become_one_line() -> None:
    from pulumi.automation import CommandError, CommandResult

    err = CommandError(CommandResult(stdout="Updating (x)\n", code=255, stderr=(
        "Updating...\n  error: creating EC2 Instance: InsufficientInstanceCapacity\n\n")))
    assert engine._last_error(err) == "error: creating EC2 Instance: InsufficientInstanceCapacity"
    assert engine._changes({"create": 12, "same": 0, "update": 1}) == "create 12, update 1"
    assert engine._changes({}) == "no changes"


def test_destroy_and_refresh_of_a_never_applied_stack_write_nothing(tmp_path: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    from fogiac.manifest.schema import load_manifest
    from fogiac.plan.compile import compile_plan

    monkeypatch.setenv("PATH", str(tmp_path / "bin"))
    fake_pulumi(tmp_path / "bin", f"v{engine.PULUMI_CLI_VERSION}")
    plan = compile_plan(load_manifest(Path(__file__).parents[3] / "examples" / "minimal.yaml"))
    assert engine.Engine(plan).destroy() == []
    assert engine.Engine(plan).refresh() == []
    assert not stack_dir(plan.stack, create=False).exists()
