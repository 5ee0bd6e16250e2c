"""A PATH without the Pulumi CLI, or with a fake one that only answers ``pulumi version`` (the CLI cannot be
installed on these machines; shared/TESTING.md)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fogiac.pulumi_engine.workspace import PULUMI_CLI_VERSION


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


@pytest.fixture
def pinned_pulumi(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("PATH", str(tmp_path / "bin"))
    return fake_pulumi(tmp_path / "bin", f"v{PULUMI_CLI_VERSION}")
