"""Issue 26 item 28: a secret is named, never held. The manifest names where the value is read at ``up``
(``{secret: env:NAME}``, ``{secret: file:PATH}``); plans, the applied document and PR comments show the
reference, and a plain env value that is not known harmless shows only as a digest."""

from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.errors import ProvisionError
from fogiac.manifest.schema import parse_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.diff import diff_documents
from fogiac.plan.document import plan_document, shown_env
from fogiac.provision import secrets
from fogiac.provision import services as svc

runner = CliRunner()

BASE = """\
name: review
cloud: {provider: aws, region: us-west-2}
network: {mode: vpn, vpc_cidr: 10.10.0.0/16, ssh_from: [10.1.2.3/32]}
nodes:
  - name: planner
    machine: c5.large
    image: ros:noetic-ros-core
    command: [rosrun, planner, planner]
"""
PLAIN = BASE + "    env: {API_TOKEN: hunter2, ROS_DOMAIN_ID: '7', LOG_LEVEL: debug}\n"
NAMED = BASE + "    env: {API_TOKEN: {secret: env:REVIEW_TOKEN}, DB_PASSWORD: {secret: file:db.pass}, LOG_LEVEL: debug}\n"


def _plan(tmp_path: Path, text: str):  # noqa: ANN202
    (tmp_path / "m.yaml").write_text(text)
    return compile_plan(parse_manifest(text, base=tmp_path))


def test_a_plain_env_value_reaches_no_comment_plan_or_json(tmp_path: Path) -> None:
    (tmp_path / "base.yaml").write_text(BASE)
    (tmp_path / "head.yaml").write_text(PLAIN)
    head, base = str(tmp_path / "head.yaml"), str(tmp_path / "base.yaml")
    for args in (["--markdown"], [], ["--json"]):
        result = runner.invoke(app, ["plan", head, "--against", base, *args])
        assert result.exit_code == 0, result.output
        assert "hunter2" not in result.output
    comment = runner.invoke(app, ["plan", head, "--against", base, "--markdown"]).output
    digest = shown_env({"API_TOKEN": "hunter2"})["API_TOKEN"]
    assert digest.startswith("sha256:") and len(digest) == 19
    assert f"    env: {{}} -> {{API_TOKEN={digest}, LOG_LEVEL=debug, ROS_DOMAIN_ID=7}}" in comment.splitlines()


def test_a_named_secret_shows_its_reference_never_its_value(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("REVIEW_TOKEN", "s3cr3t-value")
    (tmp_path / "db.pass").write_text("pa55word\n")
    (tmp_path / "base.yaml").write_text(BASE)
    (tmp_path / "head.yaml").write_text(NAMED)
    result = runner.invoke(app, ["plan", str(tmp_path / "head.yaml"), "--against", str(tmp_path / "base.yaml"),
                                 "--json"])
    assert result.exit_code == 0, result.output
    assert "s3cr3t" not in result.output and "pa55word" not in result.output
    (node,) = json.loads(result.output)["nodes"]
    assert node["env"] == {"API_TOKEN": "[secret env:REVIEW_TOKEN]",
                           "DB_PASSWORD": f"[secret file:{(tmp_path / 'db.pass').resolve()}]", "LOG_LEVEL": "debug"}


def test_an_applied_document_recorded_with_plain_values_compares_without_a_change(tmp_path: Path) -> None:
    plan = _plan(tmp_path, PLAIN)
    doc = plan_document(plan, [], manifest=tmp_path / "m.yaml")
    older = json.loads(json.dumps(doc))
    older["nodes"][0]["env"] = {"API_TOKEN": "hunter2", "LOG_LEVEL": "debug", "ROS_DOMAIN_ID": "7"}  # as recorded before
    assert diff_documents(older, doc).nodes.empty
    changed = json.loads(json.dumps(older))
    changed["nodes"][0]["env"]["API_TOKEN"] = "hunter3"
    (row,) = diff_documents(changed, doc).nodes.changed
    assert "hunter" not in repr(row)


def _where(runtime: str) -> svc.Where:
    base = "/home/ubuntu/.fogiac/review-dev/x"
    return svc.Where(layout=svc.Layout(base), runtime=runtime, master_port=11311, relay_port=11411,
                     ros_address="10.10.0.5", python="python3", code_root=f"{base}/lib", user="ubuntu")


def test_secrets_are_written_only_to_a_private_file_on_the_host(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("REVIEW_TOKEN", "s3cr3t value's")
    (tmp_path / "db.pass").write_text("pa55word\n")
    plan = _plan(tmp_path, NAMED.replace("    image: ros:noetic-ros-core\n", ""))  # a command node: either runtime
    assert "s3cr3t" not in json.dumps(plan.to_dict())
    container, native = _where(svc.CONTAINER), _where(svc.NATIVE)
    (service,) = svc.node_services(plan, plan.host("planner"), container)
    assert service.files == ((f"{container.layout.env}/node-planner.env",
                              "LOG_LEVEL=debug\nAPI_TOKEN=s3cr3t value's\nDB_PASSWORD=pa55word\n", 0o600),)
    assert "s3cr3t" not in service.script and "pa55word" not in service.script
    (service,) = svc.node_services(plan, plan.host("planner"), native)
    path = f"{native.layout.env}/node-planner.secret.sh"
    assert service.files == ((path, "export API_TOKEN='s3cr3t value'\"'\"'s'\nexport DB_PASSWORD=pa55word\n", 0o600),)
    assert f"\n. {path}\n" in service.script and "s3cr3t" not in service.script
    # what the host's shell reads back from the file is the value, whole
    (tmp_path / "s.sh").write_text(service.files[0][1])
    out = os.popen(f". {tmp_path / 's.sh'}; printf %s \"$API_TOKEN\"").read()  # noqa: S605 (our own file)
    assert out == "s3cr3t value's"


def test_up_refuses_a_missing_secret_before_creating_anything(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("REVIEW_TOKEN", raising=False)
    monkeypatch.setenv("FOGIAC_STATE_DIR", str(tmp_path / "state"))
    (tmp_path / "m.yaml").write_text(NAMED.replace("provider: aws", "provider: local").replace(
        "network: {mode: vpn, vpc_cidr: 10.10.0.0/16, ssh_from: [10.1.2.3/32]}\n", ""))
    result = runner.invoke(app, ["up", str(tmp_path / "m.yaml"), "--yes"])
    assert result.exit_code == 1, result.output
    assert result.output.strip().splitlines() == [
        f"error: node planner: env API_TOKEN: secret env:REVIEW_TOKEN: REVIEW_TOKEN is not set in the environment "
        f"`fogiac up` runs in; node planner: env DB_PASSWORD: secret file:{(tmp_path / 'db.pass').resolve()}: "
        "not a regular file"]
    assert not (tmp_path / "state").exists() or not any((tmp_path / "state").rglob("*.json"))


def test_a_secret_file_with_two_lines_is_refused_without_its_value(tmp_path: Path) -> None:
    (tmp_path / "db.pass").write_text("line one\nline two\n")
    plan = _plan(tmp_path, NAMED)
    with pytest.raises(ProvisionError) as err:
        secrets.resolve(plan.node("planner"))
    assert "line" not in str(err.value).replace("line break", "")
    assert stat.S_IMODE(0o600) == 0o600


def test_a_secret_file_others_can_read_is_used_with_a_warning(tmp_path: Path) -> None:
    """Issue 35 item 14: a world-readable ``file:`` secret was accepted silently; ssh warns of such a key."""
    (tmp_path / "db.pass").write_text("pa55\n")
    (tmp_path / "db.pass").chmod(0o644)
    plan = _plan(tmp_path, NAMED.replace("{secret: env:REVIEW_TOKEN}", "plain"))
    path = (tmp_path / "db.pass").resolve()
    with pytest.warns(secrets.SecretExposed) as said:
        assert dict(secrets.resolve(plan.node("planner"))) == {"DB_PASSWORD": "pa55"}
    assert [str(w.message) for w in said] == [
        f"secret file:{path}: other users can read it (mode 0644); keep it to yourself: chmod 600 {path}"]
    (tmp_path / "db.pass").chmod(0o600)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert dict(secrets.resolve(plan.node("planner"))) == {"DB_PASSWORD": "pa55"}


def test_up_says_so_in_one_line_before_anything_else(tmp_path: Path) -> None:
    """Through ``fogiac up`` as the operator runs it: the warning line, then (a missing secret here stops
    up before anything is created) the error line; the file's content never shown."""
    (tmp_path / "db.pass").write_text("pa55-value\n")
    (tmp_path / "db.pass").chmod(0o604)
    (tmp_path / "m.yaml").write_text(NAMED.replace("provider: aws, region: us-west-2", "provider: local").replace(
        "network: {mode: vpn, vpc_cidr: 10.10.0.0/16, ssh_from: [10.1.2.3/32]}\n", ""))
    env = {k: v for k, v in os.environ.items() if k != "REVIEW_TOKEN"}
    env["FOGIAC_STATE_DIR"] = str(tmp_path / "state")
    done = subprocess.run([sys.executable, "-m", "fogiac", "up", "m.yaml", "--yes"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)
    path = (tmp_path / "db.pass").resolve()
    assert done.returncode == 1, done.stdout + done.stderr
    assert f"warning: secret file:{path}: other users can read it (mode 0604); keep it to yourself: chmod 600 " \
           f"{path}" in done.stderr.splitlines()
    assert "pa55-value" not in done.stdout + done.stderr and "Traceback" not in done.stderr
