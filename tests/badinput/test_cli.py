"""Hostile command lines: each is refused in one line, with nothing created outside the state
folder and nothing left behind."""

from __future__ import annotations

import json
import os

from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from tests.conftest import EXAMPLES

runner = CliRunner()


@pytest.fixture
def state(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    root = tmp_path / "state" / "root"
    monkeypatch.setenv("FOGIAC_STATE_DIR", str(root))
    return root


@pytest.mark.parametrize("env", ["x/../../outside", "Prod Env", "dev\n# ExecStartPre=/bin/sh", "", "-dev"])
def test_env_must_be_dns_safe(env: str, state: Path) -> None:
    for argv in (["down", str(EXAMPLES / "minimal.yaml"), "--env", env, "--yes", "--target", "local"],
                 ["plan", str(EXAMPLES / "minimal.yaml"), "--env", env]):
        result = runner.invoke(app, argv)
        assert result.exit_code == 1, result.output
        assert result.output.strip().splitlines() == [f"error: --env {env!r} is not DNS-safe "
                                                      "(lowercase letters, digits, '-', up to 40)"]
    assert not (state.parent / "outside").exists() and not state.exists()


@pytest.mark.parametrize("robot", ["../arm1", "arm1/../../outside", "Arm1", "arm1\n", "", "-arm1"])
def test_vpn_robot_must_be_one_dns_label(robot: str, state: Path) -> None:
    """``fogiac vpn --robot NAME`` names a folder in the stack's state (its profile's): never a path."""
    for verb in ("status", "down"):
        result = runner.invoke(app, ["vpn", verb, str(EXAMPLES / "minimal.yaml"), "--robot", robot])
        assert result.exit_code == 1, result.output
        assert result.output.strip().splitlines() == [f"error: robot {robot!r}: a robot's name is one DNS label "
                                                      "(a-z, 0-9, '-', up to 63)"]
    assert not (state.parent / "outside").exists() and not state.exists()


def test_plan_out_to_a_directory_is_one_line(tmp_path: Path, state: Path) -> None:
    result = runner.invoke(app, ["plan", str(EXAMPLES / "minimal.yaml"), "--out", str(tmp_path)])
    assert result.exit_code == 1
    assert result.output.strip().splitlines() == [
        f"error: --out {tmp_path}: is a directory; name a regular file to write (or - for stdout)"]
    assert list(tmp_path.iterdir()) == []  # no temporary file left beside it


def test_plan_out_never_replaces_a_link_a_device_or_a_fifo(tmp_path: Path, state: Path) -> None:
    """Issue 26 item 3: replacing by rename turned /dev/null into a regular file and a link into a file."""
    target = tmp_path / "elsewhere.json"
    target.write_text("keep\n")
    (tmp_path / "link.json").symlink_to(target)
    os.mkfifo(tmp_path / "fifo.json")
    # (/dev/null is refused the same way as the FIFO; a test never points fogiac at the real one)
    for out, kind in ((tmp_path / "link.json", "a symbolic link"), (tmp_path / "fifo.json", "not a regular file")):
        result = runner.invoke(app, ["plan", str(EXAMPLES / "minimal.yaml"), "--out", str(out)])
        assert result.exit_code == 1
        assert result.output.strip().splitlines() == [
            f"error: --out {out}: is {kind}; name a regular file to write (or - for stdout)"]
    assert target.read_text() == "keep\n" and (tmp_path / "link.json").is_symlink()
    printed = runner.invoke(app, ["plan", str(EXAMPLES / "minimal.yaml"), "--out", "-"])
    assert printed.exit_code == 0 and json.loads(printed.output)["stack"] == "minimal-dev"
    assert not Path("-").exists()


def test_down_of_a_never_deployed_local_stack_leaves_nothing(state: Path) -> None:
    result = runner.invoke(app, ["down", str(EXAMPLES / "minimal.yaml"), "--yes", "--target", "local"])
    assert result.exit_code == 0, result.output
    assert not (state / "minimal-dev" / "local").exists()


@pytest.mark.parametrize("given", ["0.0.0.0/0", "0.0.0.0/1", "10.0.0.0/7"])
def test_preflight_refuses_a_wide_ssh_from(given: str) -> None:
    from fogiac.errors import PreflightError
    from fogiac.manifest.schema import load_manifest
    from fogiac.plan.compile import compile_plan
    from fogiac.targets.aws.api import operator_cidrs

    plan = compile_plan(load_manifest(EXAMPLES / "minimal.yaml"), target="aws")
    with pytest.raises(PreflightError, match=rf"^ssh_from: {given} cover \d+ addresses, more than a /8"):
        operator_cidrs(plan, override=given)
    assert operator_cidrs(plan, override="10.0.0.0/8") == ("10.0.0.0/8",)


@pytest.mark.parametrize("verb", [[], ["update"]])
def test_catalog_refuses_a_misspelt_region_with_did_you_mean(verb: list[str], state: Path) -> None:
    """Issue 35 item 22: ``catalog --region eu-centrl-1`` printed "0 types" and exited 0."""
    result = runner.invoke(app, ["catalog", *verb, "--region", "eu-centrl-1"])
    assert result.exit_code == 1, result.output
    assert result.output.strip().splitlines() == [
        "error: --region 'eu-centrl-1' is not an AWS region; did you mean 'eu-central-1'?"]
    assert not state.exists()


@pytest.mark.parametrize(("url", "said"), [
    ("ftp://host/x", "error: state url 'ftp://host/x': no state store for ftp:// (known: s3://)"),
    ("bucket/prefix", "error: state url 'bucket/prefix': expected s3://BUCKET/PREFIX (or unset for the stack folder)"),
    ("s3://b/../x", "error: state url 's3://b/../x': expected s3://BUCKET/PREFIX"),
])
def test_a_bad_state_url_is_one_line_and_nothing_is_written(url: str, said: str, state: Path,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FOGIAC_STATE_URL", url)
    for argv in (["status", str(EXAMPLES / "minimal.yaml")], ["ls"], ["state", "ls"],
                 ["state", "unlock", "minimal-dev", "--yes"]):
        result = runner.invoke(app, argv)
        assert result.exit_code == 1, (argv, result.output)
        assert result.output.strip().splitlines() == [said], (argv, result.output)
    assert not state.exists()
