"""The engine's workspace, which needs no Pulumi CLI: the CLI pin, the passphrase, the file backend.

The Pulumi CLI cannot be installed on these machines (shared/TESTING.md), so up/destroy through
the Automation API run only in users' CI (examples/ci/); a fake ``pulumi`` that only answers
``pulumi version`` (conftest.py) stands in where the version check is under test.
"""

from __future__ import annotations

import stat
from importlib.metadata import version
from pathlib import Path

import pytest

from fogiac.pulumi_engine.errors import EngineError
from fogiac.pulumi_engine import workspace
from fogiac.state import stack_dir

from tests.support.pulumi import fake_pulumi


def test_pin_matches_the_installed_sdk() -> None:
    major, minor, _ = workspace.PULUMI_CLI_VERSION.split(".")
    assert version("pulumi").split(".")[:2] == [major, minor]
    assert workspace.INSTALL.endswith(f"--version {workspace.PULUMI_CLI_VERSION}")


def test_missing_cli_is_one_line_with_the_install_command(no_pulumi: None) -> None:
    with pytest.raises(EngineError, match=r"^the Pulumi CLI is not installed \(fogiac needs 3\.\d+\.\d+\); install it "
                                          r"with: curl -fsSL https://get\.pulumi\.com \| sh -s -- --version 3\.\d+\.\d+$"):
        workspace.pulumi_cli()


def test_old_cli_is_refused_and_the_pinned_one_accepted(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PATH", str(tmp_path / "bin"))
    fake_pulumi(tmp_path / "bin", "v3.100.0")
    with pytest.raises(EngineError, match=r"is 3\.100\.0, fogiac needs 3\.\d+\.\d+ or a later 3\.x; install it with"):
        workspace.pulumi_cli()
    fake_pulumi(tmp_path / "bin", f"v{workspace.PULUMI_CLI_VERSION}")
    assert workspace.pulumi_cli() == tmp_path / "bin" / "pulumi"


def test_generated_passphrase_is_0600_and_stable(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("PULUMI_CONFIG_PASSPHRASE", raising=False)
    monkeypatch.delenv("PULUMI_CONFIG_PASSPHRASE_FILE", raising=False)
    first = workspace.passphrase("p-dev")
    path = stack_dir("p-dev") / workspace.PASSPHRASE_FILE
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert len(first) >= 32 and workspace.passphrase("p-dev") == first


def test_passphrase_from_the_environment_wins(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PULUMI_CONFIG_PASSPHRASE", "from-env")
    assert workspace.passphrase("q-dev") == "from-env"
    assert not (stack_dir("q-dev") / workspace.PASSPHRASE_FILE).exists()
    monkeypatch.delenv("PULUMI_CONFIG_PASSPHRASE")
    (tmp_path / "pp").write_text("from-file\n")
    monkeypatch.setenv("PULUMI_CONFIG_PASSPHRASE_FILE", str(tmp_path / "pp"))
    assert workspace.passphrase("q-dev") == "from-file"


def test_workspace_uses_a_private_file_backend(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PULUMI_CONFIG_PASSPHRASE", "x")
    env = workspace.workspace_env("w-dev")
    backend = stack_dir("w-dev") / "pulumi"
    assert env["PULUMI_BACKEND_URL"] == backend.as_uri() and env["PULUMI_BACKEND_URL"].startswith("file:///")
    assert stat.S_IMODE(backend.stat().st_mode) == 0o700
    assert env["PULUMI_CONFIG_PASSPHRASE"] == "x"
