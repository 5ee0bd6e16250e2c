"""Hostile saved plans and sealed blobs (issue 33): a plan file forged with a recomputed digest, or a blob
shaped to crash the opener, is refused in one line that carries no control character and no traceback."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac import sealed
from fogiac.cli import app
from fogiac.errors import StateError
from fogiac.plan.saved import SAVED, document_sha256

runner = CliRunner()
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _forge(doc: dict, **changes: object) -> dict:
    """``doc`` changed and its digest recomputed (what someone who may write the file could do)."""
    out = {**doc, **changes}
    return {**out, SAVED: {**out[SAVED], "sha256": document_sha256(out)}}


@pytest.mark.parametrize("field, value, said", [
    ("fogiac_version", "9.9\n\x1b[2Jok", r"was made by fogiac 9.9\n\e[2Jok"),
    ("stack", "minimal-dev\u202e", r"is for stack minimal-dev\u202e on local"),
])
def test_a_forged_plan_is_refused_in_one_visible_line(field: str, value: str, said: str, tmp_path: Path) -> None:
    manifest = tmp_path / "minimal.yaml"
    manifest.write_bytes((EXAMPLES / "minimal.yaml").read_bytes())
    saved = tmp_path / "plan.json"
    assert runner.invoke(app, ["plan", str(manifest), "--target", "local", "--out", str(saved)]).exit_code == 0
    saved.write_text(json.dumps(_forge(json.loads(saved.read_text()), **{field: value})))
    result = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes", "--plan", str(saved)])
    assert result.exit_code == 1
    (line,) = result.output.strip().splitlines()
    assert line.startswith(f"error: saved plan {saved} ") and said in line, line
    assert not any(ord(c) < 32 or c == "\u202e" for c in line)


def test_a_forged_record_version_is_shown_escaped(tmp_path: Path) -> None:
    manifest = tmp_path / "minimal.yaml"
    manifest.write_bytes((EXAMPLES / "minimal.yaml").read_bytes())
    saved = tmp_path / "plan.json"
    assert runner.invoke(app, ["plan", str(manifest), "--target", "local", "--out", str(saved)]).exit_code == 0
    doc = json.loads(saved.read_text())
    doc[SAVED] = {**doc[SAVED], "record": {"serial": "7\n\x07", "lineage": "\x1b]0;x"}}
    saved.write_text(json.dumps(_forge(doc)))
    result = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes", "--plan", str(saved)])
    assert result.exit_code == 1
    (line,) = result.output.strip().splitlines()
    assert r"was made against serial 7\n\x07 (lineage \e]0;x) of stack minimal-dev's record" in line, line


@pytest.mark.parametrize("blob", [
    b"fogiac-sealed ",
    b"fogiac-sealed 1\n{}\n",
    b"fogiac-sealed x passphrase\n{}\n" + bytes(40),
    b"fogiac-sealed 1 passphrase\n{not json\n" + bytes(40),
    b"fogiac-sealed 1 passphrase\n" + b'{"salt":"!!","n":2,"r":1,"p":1,"check":"x"}\n' + bytes(40),
    b"fogiac-sealed 1 passphrase\n" + b'{"salt":"AAAA","n":"big","r":1,"p":1,"check":"x"}\n' + bytes(40),
    b"fogiac-sealed 1 passphrase\n" + b'{"salt":"AAAA","n":2,"r":1,"p":1}\n' + bytes(40),
    b"fogiac-sealed 1 kms\n" + b'{"key":["alias/x"],"data_key":"AAAA"}\n' + bytes(40),
    b"fogiac-sealed 1 kms\n" + b'{"key":"alias/x","data_key":"%%%"}\n' + bytes(40),
    b"fogiac-sealed 1 \xff\xfe\n{}\n" + bytes(40),
    b"fogiac-sealed 1 passphrase\n\xff\n" + bytes(40),
])
def test_a_hostile_blob_is_one_line(blob: bytes, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(sealed.PASSPHRASE_ENV, "anything")
    with pytest.raises(StateError) as err:
        sealed.open_blob("certs/ca.key", blob)
    assert str(err.value).startswith("certs/ca.key: ") and "\n" not in str(err.value)
