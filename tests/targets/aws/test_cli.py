"""The deploy verbs' bad-input lines, end to end through the CLI, with LocalStack as the cloud.

Each refusal is one line, exit 1, and leaves the state directory exactly as it was. The Pulumi
CLI is absent here; where a test must get past that check, a fake ``pulumi`` that only answers
``pulumi version`` stands in (nothing reaches the engine in these tests).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from fogiac.lifecycle import sequence
from fogiac.cli import app
from fogiac.targets import get as target
from fogiac.targets.base import UpOptions
from fogiac.pulumi_engine.workspace import PULUMI_CLI_VERSION
from fogiac.errors import PreflightError

from .plans import make_plan, with_region, write_manifest
from .test_sweep import leak

pytestmark = pytest.mark.localstack


def _files(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*")) if root.exists() else []


@pytest.fixture
def state(aws_env: str) -> Path:
    return Path(os.environ["FOGIAC_STATE_DIR"])


@pytest.fixture
def with_cli(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "pulumi").write_text(f"#!/bin/sh\necho v{PULUMI_CLI_VERSION}\n")
    (bin_dir / "pulumi").chmod(0o755)
    monkeypatch.setenv("PATH", f"{bin_dir}:/usr/bin:/bin")


@pytest.fixture
def without_cli(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PATH", "/nonexistent")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))


def fogiac(*args: str) -> Any:
    return CliRunner().invoke(app, list(args))


def test_missing_pulumi_cli(state: Path, tmp_path: Path, without_cli: None) -> None:
    result = fogiac("up", str(write_manifest(tmp_path, "nocli")), "--yes")
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [
        f"error: the Pulumi CLI is not installed (fogiac needs {PULUMI_CLI_VERSION}); install it with: "
        f"curl -fsSL https://get.pulumi.com | sh -s -- --version {PULUMI_CLI_VERSION}"]
    assert _files(state) == []


def test_missing_credentials(state: Path, tmp_path: Path, with_cli: None, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("AWS_ACCESS_KEY_ID")
    monkeypatch.delenv("AWS_SECRET_ACCESS_KEY")
    doctor = fogiac("doctor", str(write_manifest(tmp_path, "nocreds")))
    assert doctor.exit_code == 1
    assert "FAIL preflight: no AWS credentials found: set AWS_PROFILE" in doctor.stdout
    for verb in ("up", "down", "sweep"):
        extra = ("--dry-run",) if verb == "sweep" else ("--yes",)
        result = fogiac(verb, str(write_manifest(tmp_path, "nocreds")), *extra)
        assert result.exit_code == 1, verb
        assert result.stderr.splitlines() == [
            "error: no AWS credentials found: set AWS_PROFILE, or AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY, "
            "or run `aws configure`"], verb
    # status of a stack never deployed from here (issue 26 item 34): "not deployed", and why the cloud was not asked
    result = fogiac("status", str(write_manifest(tmp_path, "nocreds")))
    assert result.exit_code == 0, result.output
    assert result.stdout.splitlines() == [
        "nocreds-dev: not deployed from this machine (no record); the cloud was not checked for what another machine "
        "may have left: no AWS credentials found: set AWS_PROFILE, or AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY, "
        "or run `aws configure`"]
    assert _files(state) == []


def test_type_not_offered(state: Path, tmp_path: Path, with_cli: None) -> None:
    result = fogiac("up", str(write_manifest(tmp_path, "nop3", nodes=(("gpu", "p3.2xlarge"),))), "--yes")
    assert result.exit_code == 1
    assert result.stderr.splitlines() == ["error: machine type p3.2xlarge is not offered in us-west-2"]
    assert _files(state) == []


def test_every_preflight_problem_gets_its_line(state: Path, tmp_path: Path, with_cli: None,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("FOGIAC_OPERATOR_CIDR")
    path = write_manifest(tmp_path, "twoproblems", nodes=(("gpu", "g5.xlarge"),), zone="us-west-2d")
    result = fogiac("up", str(path), "--yes", "--ssh-from", "not-an-address")
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [
        "error: zone us-west-2d does not offer g5.xlarge (zones that do: us-west-2a, us-west-2b, us-west-2c)",
        "error: --ssh-from 'not-an-address' is not an address or CIDR"]
    assert _files(state) == []


def test_unknown_region_in_a_crafted_plan(state: Path, tmp_path: Path, with_cli: None) -> None:
    plan = with_region(make_plan(tmp_path, "mars"), "mars-north-1")
    with pytest.raises(PreflightError, match=r"^unknown AWS region 'mars-north-1'$"):
        sequence.up(target("aws"), plan, UpOptions(manifest_path=tmp_path / "mars.yaml", yes=True))
    assert _files(state) == []


def test_held_lock(state: Path, tmp_path: Path, with_cli: None) -> None:
    lock = state / "held-dev" / "lock.json"
    lock.parent.mkdir(parents=True)
    lock.write_text('{"pid": 1, "host": "%s", "operation": "up", "since": "2026-01-01T00:00:00Z"}' % os.uname().nodename)
    for verb in ("up", "down"):
        result = fogiac(verb, str(write_manifest(tmp_path, "held")), "--yes")
        assert result.exit_code == 1, verb
        assert result.stderr.splitlines() == [
            f"error: stack 'held-dev' is locked by up (pid 1 on {os.uname().nodename} since 2026-01-01T00:00:00Z); "
            f"wait for it or remove {lock} if it is gone"], verb
    assert _files(state) == ["held-dev", "held-dev/lock.json"]


def test_no_terminal_needs_yes(state: Path, tmp_path: Path, with_cli: None) -> None:
    result = fogiac("up", str(write_manifest(tmp_path, "ask")))
    assert result.exit_code == 1
    assert result.stderr.splitlines() == ["error: refusing to apply without --yes: there is no terminal to ask on"]
    assert _files(state) == []


def test_down_of_a_local_stack_never_deployed_is_clean(state: Path, tmp_path: Path) -> None:
    result = fogiac("down", str(write_manifest(tmp_path, "local")), "--target", "local", "--yes")
    assert result.exit_code == 0, result.output
    assert result.stdout.strip().splitlines() == ["local-dev: not deployed; nothing to remove"]


def test_stale_saved_plan(state: Path, tmp_path: Path, with_cli: None) -> None:
    path = write_manifest(tmp_path, "stale")
    assert fogiac("plan", str(path), "--out", str(tmp_path / "plan.json")).exit_code == 0
    path.write_text(path.read_text().replace("t3.small", "t3.medium"))
    result = fogiac("up", str(path), "--yes", "--plan", str(tmp_path / "plan.json"))
    assert result.exit_code == 1
    assert result.stderr.startswith(f"error: saved plan {tmp_path / 'plan.json'} was made from another version of ")
    assert _files(state) == []


def test_doctor_reports_every_check(state: Path, tmp_path: Path, with_cli: None) -> None:
    result = fogiac("doctor", str(write_manifest(tmp_path, "doc", nodes=(("gpu", "g5.xlarge"),))))
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert lines[0].startswith("ok   Pulumi CLI: ")
    # LocalStack's IAM has no working policy simulator: said, not failed (test_iam.py stubs a real answer)
    assert lines[1].startswith("ok   IAM policy: not checked (IAM's policy simulator answered "), lines[1]
    # the account's fogiac-boundary (issue 35): LocalStack has none, and this plan makes no role that needs it
    assert lines[2] == ("ok   permissions boundary: the account has no arn:aws:iam::000000000000:policy/fogiac-boundary; "
                        "this plan makes no role, so it needs none (flow_logs: true would: an administrator creates "
                        "it once from `python -m fogiac.targets.aws.iam --boundary`)"), lines[2]
    assert lines[3:] == ["ok   credentials: account 000000000000", "ok   region: us-west-2",
                         "ok   zone: us-west-2a offers g5.xlarge", "ok   images: gpu: ami-0a1b2c3d4e5f60003",
                         "ok   ssh_from: 203.0.113.7/32",
                         # LocalStack has no Service Quotas: said, not failed (test_quotas.py stubs a real answer)
                         "ok   vCPU quotas: not checked: cannot read EC2 vCPU quotas in us-west-2: InternalFailure"]
    assert _files(state) == []


def test_sweep_and_status_verbs(state: Path, tmp_path: Path, ec2: Any, acm: Any,
                               monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "200")
    path = write_manifest(tmp_path, "leaky")
    made = leak(ec2, acm, "leaky-dev")
    shown = fogiac("status", str(path))
    assert shown.exit_code == 0 and made["instance"] in shown.stdout and "t3.small" in shown.stdout
    doc = json.loads(fogiac("status", str(path), "--json").stdout)
    assert [(h["host"], h["instance_id"], h["state"]) for h in doc["hosts"]] == [
        (made["instance"], made["instance"], "running")]  # no fogiac:node tag: named by its id
    dry = fogiac("sweep", str(path), "--dry-run")
    assert dry.exit_code == 0
    assert f"would delete: vpc {made['vpc']}" in dry.stdout.splitlines()
    assert fogiac("sweep", str(path)).stderr.splitlines() == [
        "error: refusing to sweep without --yes: there is no terminal to ask on"]
    done = fogiac("sweep", str(path), "--yes")
    assert done.exit_code == 0, done.output
    assert f"deleted: instance {made['instance']}" in done.stdout.splitlines()
    assert "not checked: client-vpn-endpoint (not supported by this endpoint: InternalFailure)" in done.stderr
    assert fogiac("sweep", str(path), "--dry-run").stdout == ""
    assert fogiac("status", str(path)).stdout.splitlines() == [  # asked, AWS confirms nothing (issue 26 item 34)
        "leaky-dev: not deployed (the cloud reports no instances; `fogiac sweep --dry-run` lists anything else "
        "tagged with the stack)"]
