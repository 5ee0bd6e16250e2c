"""Issue 26 item 28, private registries: the password is a named secret, shown by reference in the plan,
and handed to the engine's ``login --password-stdin`` on the host through a 0600 file that is removed
at once. The host is a real local sandbox; the engine is a stand-in script that records what it got."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.errors import ProvisionError
from fogiac.hostmodel import Layout, NativeRos
from fogiac.manifest.schema import parse_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import HostSpec, Plan
from fogiac.provision.local import LocalHost
from fogiac.provision.runtimes.container import ContainerRuntime

MANIFEST = """\
name: private
cloud:
  provider: local
  registries:
    - {server: "registry.acme.io:5000", username: robot, password: {secret: "env:ACME_TOKEN"}}
nodes:
  - name: det
    machine: t3.small
    image: registry.acme.io:5000/vision/det:1
"""
ENGINE = """\
#!/bin/bash
# a stand-in container engine: records a login (its arguments and what came on stdin) and its password file
if [ "$1" = login ]; then
  { printf '%s\\n' "$*"; cat; } > "$(dirname "$0")/login.seen"
  exit "$(cat "$(dirname "$0")/login.exit" 2>/dev/null || echo 0)"  # a file: a sandbox's environment is allowlisted
fi
exit 0
"""


@dataclass
class _Run:
    plan: Plan
    spec: HostSpec
    host: LocalHost
    engine: str
    ros_image: str = ""
    facts: None = None
    images: dict[str, str] = field(default_factory=dict)

    @property
    def layout(self) -> Layout:
        return Layout(self.host.base)

    @property
    def native_ros(self) -> NativeRos:
        return NativeRos(check="true", needs="", packages=(), install="", by_hand="")


def _run(tmp_path: Path) -> _Run:
    plan = compile_plan(parse_manifest(MANIFEST, base=tmp_path))
    engine = tmp_path / "engine"
    engine.write_text(ENGINE)
    engine.chmod(0o755)
    host = LocalHost(name="det", base=str(tmp_path / "sandbox"))
    host.connect()
    (tmp_path / "sandbox" / "tmp").mkdir()
    return _Run(plan=plan, spec=plan.host("det"), host=host, engine=str(engine))


def test_the_password_reaches_the_engines_stdin_only(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ACME_TOKEN", "tok-3141")
    run = _run(tmp_path)
    changes = ContainerRuntime().prepare(run, facts=None)  # type: ignore[arg-type]
    assert "logged in to registry.acme.io:5000" in changes
    seen = (tmp_path / "login.seen").read_text().splitlines()
    assert seen[0].startswith("login registry.acme.io:5000 --username robot --password-stdin")
    assert seen[1] == "tok-3141" and "tok-3141" not in seen[0]
    assert not any((tmp_path / "sandbox" / "tmp").iterdir())  # the password file is gone


def test_a_failed_login_is_one_line_without_the_password(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ACME_TOKEN", "tok-3141")
    run = _run(tmp_path)
    (tmp_path / "login.exit").write_text("1\n")
    with pytest.raises(ProvisionError, match=r"^det: .*engine login to registry.acme.io:5000 as robot failed") as err:
        ContainerRuntime().prepare(run, facts=None)  # type: ignore[arg-type]
    assert "tok-3141" not in str(err.value)
    assert not any((tmp_path / "sandbox" / "tmp").iterdir())


def test_the_plan_names_the_registry_and_its_secret_never_the_value(tmp_path: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ACME_TOKEN", "tok-3141")
    (tmp_path / "base.yaml").write_text(MANIFEST)
    (tmp_path / "head.yaml").write_text(MANIFEST.replace("username: robot", "username: robot2"))
    doc = runner_json(["plan", str(tmp_path / "base.yaml"), "--json"])
    assert doc["registries"] == [{"server": "registry.acme.io:5000", "username": "robot",
                                  "password": "[secret env:ACME_TOKEN]"}]
    result = CliRunner().invoke(app, ["plan", str(tmp_path / "head.yaml"), "--against", str(tmp_path / "base.yaml")])
    assert "tok-3141" not in result.output
    assert any(line.strip().startswith("~ registries: [{server=registry.acme.io:5000, username=robot, "
                                       "password=[secret env:ACME_TOKEN]}] -> [{server=registry.acme.io:5000, "
                                       "username=robot2") for line in result.output.splitlines()), result.output


def test_a_plain_password_is_refused(tmp_path: Path) -> None:
    (tmp_path / "m.yaml").write_text(MANIFEST.replace('{secret: "env:ACME_TOKEN"}', "hunter2"))
    result = CliRunner().invoke(app, ["validate", str(tmp_path / "m.yaml")])
    assert result.exit_code == 1
    assert result.output.strip().endswith("cloud.registries[0].password: a password is never written in the "
                                          "manifest: name where it is read, {secret: env:NAME} or {secret: file:PATH}")
    assert "hunter2" not in result.output


def runner_json(args: list[str]) -> dict:
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)

