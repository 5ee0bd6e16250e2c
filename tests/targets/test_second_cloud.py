"""A second cloud, defined only in the tests (``tests/plugins/nimbus/``) and registered through an entry
point, goes through the one lifecycle: its own catalogue and ``cloud:`` variant validate the manifest
in its words, its stack program declares the plan's resources through fogiac's one Pulumi engine (under
Pulumi's mocks, which are its API), ``up`` creates its
machines and fogiac provisions them and connects the robot's edge, a planning request crosses the relay,
``status`` reports it, and ``down`` deletes the machines and leaves no process. Nothing in fogiac/
names it."""

from __future__ import annotations

import json
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac import targets
from fogiac.cli import app
from fogiac.procs import free_port
from tests.plugins.install import installed
from tests.plugins.nimbus import ENTRY_POINTS
from tests.support.procs import alive, started_pids
from tests.targets.test_local import ask_planner

runner = CliRunner()


@pytest.fixture
def nimbus(tmp_path: Path) -> Iterator[None]:
    with installed(tmp_path / "site", "fogiac_nimbus", ENTRY_POINTS):
        yield


def _manifest(tmp_path: Path, *, region: str = "moon-1", machine: str = "machine: {vcpus: '>=8'}",
              edge_port: int = 11311) -> Path:
    path = tmp_path / "nimbus.yaml"
    path.write_text(f"""\
name: skyward
cloud:
  provider: nimbus
  region: {region}
edge:
  ros_master: http://127.0.0.1:{edge_port}
nodes:
  - name: planner
    {machine}
    workload: motion_planning
""")
    return path


def run(*args: str) -> tuple[int, str]:
    result = runner.invoke(app, list(args))
    return result.exit_code, result.output


def test_the_entry_point_is_the_whole_registration(nimbus: None) -> None:
    assert "nimbus" in targets.names()
    assert targets.get("nimbus").name == "nimbus"


def test_its_catalogue_and_words_validate_the_manifest(nimbus: None, tmp_path: Path) -> None:
    code, out = run("validate", str(_manifest(tmp_path)))
    assert code == 0, out
    assert out.strip().endswith("valid (1 node, 1 host, target nimbus)")
    code, out = run("validate", str(_manifest(tmp_path, region="venus-3")))
    assert code == 1 and "'venus-3' is not a nimbus region" in out, out
    code, out = run("validate", str(_manifest(tmp_path, machine="machine: n9.huge")))
    assert code == 1 and "'n9.huge' is not a nimbus shape" in out, out


def test_another_problem_does_not_send_its_machines_to_the_default_catalogue(nimbus: None, tmp_path: Path) -> None:
    path = _manifest(tmp_path)
    path.write_text(path.read_text() + "tags: {'aws:x': y}\n")
    code, out = run("validate", str(path))
    assert code == 1
    assert out.splitlines() == [f"{path}:11: tags: tag 'aws:x' uses a reserved prefix (fogiac:, aws:)"], out


def test_its_stack_program_declares_the_plan_under_mocks(nimbus: None, tmp_path: Path) -> None:
    code, out = run("plan", str(_manifest(tmp_path)), "--json")
    assert code == 0, out
    doc = json.loads(out)
    (machine,) = doc["resources"]
    assert machine["type"] == "nimbus:compute:Machine" and machine["inputs"]["shape"] == "n1.large"
    assert doc["hosts"][0]["machine"] == "n1.large"  # the cheapest shape with 8 vCPUs or more
    assert doc["cost"]["hourly_usd"] == pytest.approx(0.31)


@pytest.mark.ros
@pytest.mark.skipif(shutil.which("roscore") is None, reason="needs Debian's ros-core (roscore)")
def test_up_request_status_down_through_the_one_lifecycle(nimbus: None, tmp_path: Path, _state_dir: Path) -> None:
    edge_port = free_port()
    manifest = _manifest(tmp_path, edge_port=edge_port)
    pids: list[int] = []
    try:
        code, out = run("up", str(manifest), "--yes", "--start-edge-master")
        assert code == 0, out
        cloud = json.loads((_state_dir / "skyward-dev" / "nimbus-cloud.json").read_text())
        (made,) = cloud.values()
        assert f"planner: {made['id']} n1.large public 127.0.0.1" in out
        pids = started_pids(_state_dir)
        assert pids, "up started no supervised process"

        answer = ask_planner(edge_port, cwd=tmp_path)
        assert answer["solved"] and answer["free"], answer

        code, out = run("status", str(manifest), "--json")
        assert code == 0, out
        doc = json.loads(out)
        assert doc["target"] == "nimbus" and doc["partial"] is False
        assert doc["hosts"] == [{"host": "planner", "id": made["id"], "shape": "n1.large", "region": "moon-1"}]
        assert doc["relays"][0]["host"] == "planner"
        code, out = run("status", str(manifest))
        assert f"planner: {made['id']} n1.large in moon-1" in out

        code, again = run("up", str(manifest), "--yes")  # the same machine, found again: nothing new
        assert code == 0, again
        assert json.loads((_state_dir / "skyward-dev" / "nimbus-cloud.json").read_text()) == cloud
    finally:
        code, out = run("down", str(manifest), "--yes")
    assert code == 0, out
    assert out.splitlines()[-1].endswith("nothing left"), out
    assert f"machine {made['id']}" in out
    assert [pid for pid in pids if alive(pid)] == []
    assert not (_state_dir / "skyward-dev" / "nimbus-cloud.json").exists()
    code, out = run("status", str(manifest))
    assert out.strip() == "skyward-dev: not deployed"
