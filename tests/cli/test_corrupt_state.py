"""Corrupt state files (issue 26 item 16): one line naming the file, no traceback, never "no record".

``stack.json`` and ``applied.json`` are written by fogiac only, but an editor, a full disk or a careless
``jq`` can leave anything there. A record that is a list or null is not "nothing deployed" (status and
down would then go to the manifest's target), and a manifest path read from it is printed escaped.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from fogiac.cli import app

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
runner = CliRunner()


def cli(*args: str) -> tuple[int, str]:
    result = runner.invoke(app, list(args))
    return result.exit_code, result.output


@pytest.fixture
def stack(tmp_path: Path, _state_dir: Path) -> tuple[Path, Path, dict[str, Any]]:
    """A manifest, its stack folder, and a record and applied document as a complete local up leaves them."""
    manifest = tmp_path / "fogiac.yaml"
    shutil.copy(EXAMPLES / "minimal.yaml", manifest)
    code, out = cli("plan", str(manifest), "--json", "--target", "local")
    assert code == 0, out
    applied = json.loads(out)
    folder = _state_dir / "minimal-dev"
    folder.mkdir()
    (folder / "applied.json").write_text(json.dumps(applied))
    record = {"stack": "minimal-dev", "target": "local", "manifest": str(manifest.resolve()), "state": "complete",
              "since": "2026-01-01T00:00:00Z", "since_epoch": 1.0, "plan_digest": applied["plan_digest"]}
    (folder / "stack.json").write_text(json.dumps(record))
    assert cli("plan", str(manifest), "--detailed-exitcode")[0] == 0  # the good state: no changes
    return manifest, folder, record


def _one_line_error(code: int, out: str, *needles: str) -> None:
    assert code == 1, out
    assert "Traceback" not in out and len(out.strip().splitlines()) == 1, out
    for needle in needles:
        assert needle in out, out


RECORDS = {
    "list": [], "null": None, "number": 5,
    "state-int": {"state": 5}, "state-unknown": {"state": "gone"}, "since-epoch-text": {"since_epoch": "x"},
    "target-int": {"target": 3}, "digest-list": {"plan_digest": [1]}, "other-stack": {"stack": "robot-dev"},
}


@pytest.mark.parametrize("case", RECORDS, ids=list(RECORDS))
def test_a_corrupt_record_is_one_line_not_no_record(stack: tuple[Path, Path, dict[str, Any]], case: str) -> None:
    manifest, folder, record = stack
    value = RECORDS[case]
    (folder / "stack.json").write_text(json.dumps({**record, **value} if isinstance(value, dict) else value))
    for verb in (("plan", str(manifest), "--detailed-exitcode"), ("status", str(manifest))):
        _one_line_error(*cli(*verb), "stack.json: not a fogiac deployment record")


APPLIED = {"list": [], "null": None, "resources-text": {"resources": "x"}, "hosts-number": {"hosts": 5},
           "node-rows-text": {"nodes": ["a"]}, "cost-text": {"cost": "free"}, "host-row-odd": {"hosts": [{"x": 1}]}}


@pytest.mark.parametrize("case", APPLIED, ids=list(APPLIED))
def test_a_corrupt_applied_document_is_one_line(stack: tuple[Path, Path, dict[str, Any]], case: str) -> None:
    manifest, folder, _record = stack
    value = APPLIED[case]
    applied = json.loads((folder / "applied.json").read_text())
    (folder / "applied.json").write_text(json.dumps({**applied, **value} if isinstance(value, dict) else value))
    _one_line_error(*cli("plan", str(manifest), "--detailed-exitcode"), "applied.json: not a plan document")


def test_a_recorded_manifest_path_is_printed_escaped(stack: tuple[Path, Path, dict[str, Any]]) -> None:
    manifest, folder, record = stack
    (folder / "stack.json").write_text(json.dumps({**record, "manifest": "/x/\x1b[31mevil\nline.yaml"}))
    code, out = cli("status", str(manifest))
    _one_line_error(code, out, r"/x/\x1b[31mevil\nline.yaml")
    assert "\x1b" not in out
