"""A target whose platform runs the nodes itself, defined only in the tests (``tests/plugins/stratus/``) and
registered through an entry point: it declares no provisioning, so ``fogiac up`` opens no host (no SSH,
no sandbox of fogiac's, no supervisor of fogiac's beside the nodes), asks the target for the links and
starts only the edge's end. The platform's pods (a real roscore, the real motion-planning node and the
relay's cloud end) answer a planning request from the robot's side through the relay; ``status`` reports
them; ``down`` has the platform stop them and leaves no process running. Nothing in fogiac/ names it."""

from __future__ import annotations

import json
import shutil
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac import targets
from fogiac.cli import app
from fogiac.lifecycle.driver import Feature
from fogiac.procs import free_port
from fogiac.provision import recorded_access
from tests.conftest import EXAMPLES
from tests.plugins.install import installed
from tests.plugins.stratus import ENTRY_POINTS
from tests.plugins.stratus.platform import members
from tests.support.procs import alive, started_pids
from tests.targets.test_local import ask_planner

runner = CliRunner()
STACK = "motion-planning-dev"


@pytest.fixture
def stratus(tmp_path: Path) -> Iterator[None]:
    with installed(tmp_path / "site", "fogiac_stratus", ENTRY_POINTS):
        yield


def run(*args: str) -> tuple[int, str]:
    result = runner.invoke(app, list(args))
    return result.exit_code, result.output


def test_it_is_a_target_without_provisioning(stratus: None) -> None:
    chosen = targets.get("stratus")
    assert Feature.PROVISIONS not in chosen.features
    assert all(Feature.PROVISIONS in targets.get(name).features for name in ("aws", "hosts", "local"))


def test_fogiac_provision_refuses_it_in_one_line(stratus: None) -> None:
    code, out = run("provision", str(EXAMPLES / "motion-planning.yaml"), "--target", "stratus")
    assert code == 1
    assert out.strip().splitlines() == [
        "error: target stratus runs its nodes itself: `fogiac provision` has nothing to provision there; "
        "`fogiac up` starts them"], out


@pytest.mark.ros
@pytest.mark.skipif(shutil.which("roscore") is None, reason="needs Debian's ros-core (roscore)")
def test_up_request_status_down_with_nodes_the_platform_runs(stratus: None, tmp_path: Path, _state_dir: Path) -> None:
    edge_port = free_port()
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text((EXAMPLES / "motion-planning.yaml").read_text().replace(
        "ros_master: http://localhost:11311", f"ros_master: http://127.0.0.1:{edge_port}"))
    folder = _state_dir / STACK
    sessions: set[int] = set()
    pids: list[int] = []
    try:
        code, out = run("up", str(manifest), "--target", "stratus", "--yes", "--start-edge-master")
        assert code == 0, out
        (pod,) = json.loads((folder / "stratus.json").read_text()).values()
        sessions = set(pod["sessions"].values())
        assert set(pod["sessions"]) == {"ros-master", "node-planner", "relay-cloud"}
        assert members(sessions), "the platform runs no process"
        assert f"planner: relay 127.0.0.1:{pod['relay_port']} <-> edge http://127.0.0.1:{edge_port}" in out
        assert f"planner: {pod['id']} " in out
        assert "provisioning:" not in out  # no host was provisioned
        # fogiac opened no host and recorded no access to one; its supervisor runs the edge's end only
        assert recorded_access(folder, targets.get("stratus").access_from) == {}
        pids = started_pids(_state_dir)
        supervised = sorted(p.relative_to(folder).parts[0] for p in folder.rglob("*.child"))  # a supervisor's child
        assert pids and set(supervised) == {"edge"}, supervised

        for verb in ("logs", "ssh"):  # nothing of fogiac's runs there to open
            code, out = run(verb, "planner", str(manifest))
            assert code == 1 and out.strip().splitlines() == [
                "error: target stratus runs its nodes itself: fogiac reaches none of its hosts, so node 'planner' "
                "has no host to open here"], out

        answer = ask_planner(edge_port, cwd=tmp_path)
        assert answer["solved"] and answer["poses"] >= 2 and answer["free"], answer

        deadline = time.monotonic() + 15  # the edge relay rewrites its stats once a second
        while True:
            code, out = run("status", str(manifest), "--json")
            assert code == 0, out
            doc = json.loads(out)
            if doc["relays"] and doc["relays"][0].get("connected") or time.monotonic() > deadline:
                break
            time.sleep(0.5)
        assert doc["target"] == "stratus" and doc["partial"] is False
        assert doc["hosts"] == [{"host": "planner", "pod": pod["id"], "running": True,
                                 "processes": len(members(sessions))}]
        assert doc["relays"][0]["host"] == "planner" and doc["relays"][0]["connected"] is True

        code, again = run("up", str(manifest), "--yes")  # the pod still runs: the platform keeps it
        assert code == 0, again
        assert json.loads((folder / "stratus.json").read_text())[f"{STACK}-planner"]["id"] == pod["id"]
    finally:
        code, out = run("down", str(manifest), "--yes")
    assert code == 0, out
    assert out.splitlines()[-1].endswith("nothing left"), out
    assert f"pod {pod['id']}" in out
    assert members(sessions) == []  # no process of the pod's, children included
    assert [pid for pid in pids if alive(pid)] == []
    assert not (folder / "stratus.json").exists() and not (folder / "stratus").exists()
    code, out = run("status", str(manifest))
    assert out.strip() == f"{STACK}: not deployed"
