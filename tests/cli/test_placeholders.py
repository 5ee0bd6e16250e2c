"""Issue 26 item 32: placeholders copied from the documentation (an image at an example registry, ssh_from
in a documentation address range) are warned about at ``validate`` and ``plan``, and refused at ``up``
unless forced."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.plan.placeholders import documentation_range, placeholder_image

runner = CliRunner()

AWS = """\
name: sample
cloud: {provider: aws, region: us-west-2}
network: {mode: proxy, ssh_from: [198.51.100.0/24]}
nodes:
  - name: det
    machine: t3.small
    image: ghcr.io/example/detector:jazzy
"""
LOCAL = """\
name: sample
cloud: {provider: local}
nodes:
  - name: det
    machine: t3.small
    image: registry.example.com/team/detector:1
"""
IMAGE_LINE = "warning: node det: image {image} is a documentation placeholder (an example registry); name your own image"
SSH_LINE = ("warning: network.ssh_from: 198.51.100.0/24 is a documentation address range (RFC 5737/3849), nobody's "
            "network; name your own")


@pytest.mark.parametrize(("image", "placeholder"), [
    ("registry.example.com/team/app:1", True), ("ghcr.io/example/detector:jazzy", True),
    ("docker.io/example/app", True), ("my.registry.test:5000/app", True), ("ros:noetic-ros-core", False),
    ("example/grasp:1", False), ("ghcr.io/examples-org/app:1", False), ("ghcr.io/acme/example:1", False),
])
def test_placeholder_images(image: str, placeholder: bool) -> None:
    assert placeholder_image(image) is placeholder


def test_documentation_ranges() -> None:
    assert documentation_range("203.0.113.7/32") and documentation_range("192.0.2.0/24")
    assert documentation_range("2001:db8::1/128")
    assert not documentation_range("203.0.112.0/23") and not documentation_range("10.0.0.0/8")


def test_validate_and_plan_warn(tmp_path: Path) -> None:
    (tmp_path / "m.yaml").write_text(AWS)
    result = runner.invoke(app, ["validate", str(tmp_path / "m.yaml")])
    assert result.exit_code == 0, result.output
    assert result.stderr.splitlines() == [IMAGE_LINE.format(image="ghcr.io/example/detector:jazzy"), SSH_LINE]
    result = runner.invoke(app, ["plan", str(tmp_path / "m.yaml"), "--json"])
    assert result.exit_code == 0
    assert result.stderr.splitlines() == [line + "; `fogiac up` refuses it without --force" for line in
                                          (IMAGE_LINE.format(image="ghcr.io/example/detector:jazzy"), SSH_LINE)]
    comment = runner.invoke(app, ["plan", str(tmp_path / "m.yaml"), "--markdown"]).stdout.splitlines()
    assert "> **Documentation placeholders (`fogiac up` refuses them)**" in comment
    assert "> - network.ssh\\_from: 198.51.100.0/24 is a documentation address range (RFC 5737/3849), nobody's " \
           "network; name your own" in comment


def test_ssh_from_is_no_placeholder_where_the_target_opens_nothing(tmp_path: Path) -> None:
    (tmp_path / "m.yaml").write_text(AWS)
    result = runner.invoke(app, ["validate", str(tmp_path / "m.yaml"), "--target", "local"])
    assert SSH_LINE not in result.stderr.splitlines()


def test_up_refuses_placeholders_unless_forced(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FOGIAC_STATE_DIR", str(tmp_path / "state"))
    (tmp_path / "m.yaml").write_text(LOCAL)
    result = runner.invoke(app, ["up", str(tmp_path / "m.yaml"), "--yes"])
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [
        "error: node det: image registry.example.com/team/detector:1 is a documentation placeholder (an example "
        "registry); name your own image; up refuses documentation placeholders (pass --force to deploy anyway)"]
    assert not any((tmp_path / "state").rglob("*.json")) if (tmp_path / "state").exists() else True
