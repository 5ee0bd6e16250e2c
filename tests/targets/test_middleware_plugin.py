"""A middleware defined only in the tests (``tests/plugins/beacon/``) and registered through an entry point
goes through the one lifecycle on the local target: it serves a ROS distribution fogiac does not list
(``lighthouse``), validates its own ``beacon:`` block in its own words, its settings reach the host
service's command line, ``up`` starts each host's beacon and the edge's listener, ``status`` shows the
link connected, and ``down`` leaves no process. Nothing in fogiac/ names it."""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.manifest.schema import load_manifest
from fogiac.net import middleware
from fogiac.plan.compile import compile_plan
from tests.plugins.beacon import ENTRY_POINTS
from tests.plugins.install import installed
from tests.support.procs import alive, started_pids

runner = CliRunner()


@pytest.fixture
def beacon(tmp_path: Path) -> Iterator[None]:
    with installed(tmp_path / "site", "fogiac_beacon", ENTRY_POINTS):
        yield
    middleware.unregister("beacon")  # the loaded halves are cached per process


def _manifest(tmp_path: Path, block: str = "beacon: {interval_s: 0.2, greeting: ahoy}", *,
              distro: str = "lighthouse") -> Path:
    path = tmp_path / "beacon.yaml"
    path.write_text(f"""\
name: shore
ros: {{distro: {distro}}}
cloud: {{provider: local, runtime: native}}
nodes:
  - name: keeper
    machine: t3.micro
    command: [sleep, "600"]
{block}
""")
    return path


def run(*args: str) -> tuple[int, str]:
    result = runner.invoke(app, list(args))
    return result.exit_code, result.output


def test_the_entry_point_is_the_whole_registration(beacon: None) -> None:
    assert "beacon" in middleware.names()
    assert middleware.for_distro("lighthouse").name == "beacon"


def test_without_the_plugin_its_distro_and_block_are_refused(tmp_path: Path) -> None:
    code, out = run("validate", str(_manifest(tmp_path)))
    assert code == 1
    assert "ros.distro: 'lighthouse' is not one of 'noetic', 'humble', 'jazzy', 'kilted'" in out, out
    assert "beacon: unknown key; valid: 'name', 'ros'" in out, out


def test_its_block_is_validated_in_its_words(beacon: None, tmp_path: Path) -> None:
    code, out = run("validate", str(_manifest(tmp_path)))
    assert code == 0, out
    path = _manifest(tmp_path, "beacon:\n  interval_s: 0\n  greeting: 'two words'\n  intervl: 1")
    code, out = run("validate", str(path))
    assert code == 1
    assert out.splitlines() == [
        f"{path}:9: beacon.interval_s: a beacon beats every 0.05 to 60 seconds, not every 0",
        f"{path}:10: beacon.greeting: 'two words' is not one word a beacon can shout (letters only)",
        f"{path}:11: beacon.intervl: unknown key; did you mean 'interval_s'?",
    ], out
    code, out = run("validate", str(_manifest(tmp_path, "beacn: {}")))  # other keys: refused as before
    assert code == 1 and "beacn: unknown key; did you mean 'beacon'?" not in out and "beacn: unknown key" in out
    code, out = run("validate", str(_manifest(tmp_path, distro="noetic")))  # its block, another middleware
    assert code == 1
    assert ": beacon: the beacon middleware's block, but ROS noetic crosses through relay" in out, out


def test_another_problem_reports_alone(beacon: None, tmp_path: Path) -> None:
    path = _manifest(tmp_path, "tags: {'aws:x': y}")  # the checks across fields take its distribution too
    code, out = run("validate", str(path))
    assert code == 1
    assert out.splitlines() == [f"{path}:8: tags: tag 'aws:x' uses a reserved prefix (fogiac:, aws:)"], out


def test_its_block_reaches_the_plan(beacon: None, tmp_path: Path) -> None:
    code, out = run("plan", str(_manifest(tmp_path)), "--target", "local", "--json")
    assert code == 0, out
    doc = json.loads(out)
    assert doc["middleware"]["name"] == "beacon" and doc["middleware"]["ros_distro"] == "lighthouse"
    plan = compile_plan(load_manifest(_manifest(tmp_path)), target="local")
    assert plan.middleware == "beacon" and plan.ros_distro == "lighthouse"
    assert plan.middleware_settings == (("greeting", "ahoy"), ("interval_s", 0.2))
    plain = compile_plan(load_manifest(_manifest(tmp_path, "")), target="local")
    assert plain.middleware_settings == () and "middleware_settings" not in plain.to_dict()  # digests as before


def _status(manifest: Path) -> dict:
    code, out = run("status", str(manifest), "--target", "local", "--json")
    assert code == 0, out
    return json.loads(out)


def test_up_status_down_through_the_one_lifecycle(beacon: None, tmp_path: Path, _state_dir: Path) -> None:
    manifest = _manifest(tmp_path)
    pids: list[int] = []
    try:
        code, out = run("up", str(manifest), "--target", "local", "--yes")
        assert code == 0, out
        assert "beacon listener dialing 127.0.0.1:" in out, out
        pids = started_pids(_state_dir)
        assert pids, "up started no supervised process"
        scripts = list(_state_dir.rglob("services/beacon.sh"))
        assert scripts and "--interval 0.2 --greeting ahoy" in scripts[0].read_text()  # the block, on its line
        deadline = time.monotonic() + 15
        while True:
            doc = _status(manifest)
            links = doc["relays"]  # the status document's key for every middleware's links
            if links and links[0]["connected"] and links[0]["beats"] >= 2 or time.monotonic() > deadline:
                break
            time.sleep(0.3)
        assert links and links[0]["host"] == "keeper" and links[0]["connected"], doc
        assert links[0]["interval_s"] == 0.2  # what the host's beacon says it was started with
        (host,) = doc["hosts"]
        assert [(n["node"], n["running"]) for n in host["nodes"]] == [("keeper", True)]  # natively, no ROS
    finally:
        code, out = run("down", str(manifest), "--target", "local", "--yes")
    assert code == 0, out
    assert [pid for pid in pids if alive(pid)] == []
    code, out = run("status", str(manifest), "--target", "local")
    assert out.strip() == "shore-dev: not deployed", out
