"""Shared fixtures: every test gets its own fogiac state directory."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
EXAMPLES = REPO / "examples"


@pytest.fixture(autouse=True)
def _state_dir(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> Path:
    state = tmp_path_factory.mktemp("fogiac-state")
    monkeypatch.setenv("FOGIAC_STATE_DIR", str(state))
    return state
