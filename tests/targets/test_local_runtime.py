"""``cloud.runtime: auto`` on ``local`` is decided at plan time (issue 26 item 31).

An image node passed validate and plan and failed at ``up`` ("the host has no working container
engine (docker info failed)") while podman worked, leaving a partial stack. The host is this
machine: plan asks docker, then podman, and refuses in one line when neither answers.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.manifest.schema import parse_manifest
from fogiac.plan.compile import compile_plan
from fogiac.targets.local import placement

runner = CliRunner()
MANIFEST = """name: boxes
cloud: {{provider: local, runtime: {runtime}}}
nodes:
  - {{name: talker, machine: t3.small, image: 'ros:noetic-ros-core', command: [sleep, '60']}}
  - {{name: plain, machine: t3.small, command: [sleep, '60']}}
"""


@pytest.fixture(autouse=True)
def _asked_anew() -> Iterator[None]:
    placement.answering_engine.cache_clear()
    yield
    placement.answering_engine.cache_clear()


def _engine(folder: Path, name: str, *, answers: bool) -> None:
    """A stand-in for a machine's engine binary: `info` answers or fails, as a broken docker socket does."""
    path = folder / name
    path.write_text(f"#!/bin/sh\nexit {0 if answers else 1}\n")
    path.chmod(0o755)


def test_no_engine_is_refused_at_plan_naming_the_setting(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                         _state_dir: Path) -> None:
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    _engine(bin_dir, "docker", answers=False)  # podman: not installed at all
    monkeypatch.setenv("PATH", str(bin_dir))
    path = tmp_path / "fogiac.yaml"
    path.write_text(MANIFEST.format(runtime="auto"))
    result = runner.invoke(app, ["plan", str(path)])
    assert result.exit_code == 1, result.output
    assert result.output.strip().splitlines() == [
        "error: node talker runs a container image, but no container engine answers on this machine (`docker info` "
        "and `podman info` failed): install one (apt-get install podman runc; cloud.runtime: container then uses "
        "it), or make the node a launch, workload or command node"]
    assert not (_state_dir / "boxes-dev").exists()


def test_podman_alone_makes_the_hosts_run_containers(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    _engine(bin_dir, "docker", answers=False)
    _engine(bin_dir, "podman", answers=True)
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{os.environ['PATH']}")
    plan = compile_plan(parse_manifest(MANIFEST.format(runtime="auto")), target="local")
    assert {h.name: h.runtime for h in plan.hosts} == {"talker": "container", "plain": "container"}


def test_docker_answering_keeps_auto_and_native_needs_no_engine(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    _engine(bin_dir, "docker", answers=True)
    monkeypatch.setenv("PATH", str(bin_dir))
    assert {h.runtime for h in compile_plan(parse_manifest(MANIFEST.format(runtime="auto")), target="local").hosts} \
        == {"auto"}
    _engine(bin_dir, "docker", answers=False)
    placement.answering_engine.cache_clear()
    plain = MANIFEST.format(runtime="auto").split("  - {name: talker")[0] + \
        "  - {name: plain, machine: t3.small, command: [sleep, '60']}\n"
    assert {h.runtime for h in compile_plan(parse_manifest(plain), target="local").hosts} == {"auto"}
