"""Issue 34, ROS 2 on ``hosts``: ``fogiac up`` deploys a Zenoh fleet to a lab machine reached over real SSH.

``test_fleet_zenoh_local`` walks the fleet on this machine; here the Zenoh gate (``fogiac.net.zenoh.gate``:
TLS 1.3 with the stack's CA, one Zenoh router per admitted robot behind it) runs on a namespace lab host with
its own sshd (``tests/provision/sshlab.py``), so what only ``hosts`` and ``aws`` do is exercised: the fleet
file written on the host over SSH (0600 there), the host's router reading a revocation from it, each robot's
edge router on this machine dialing the host's address. One walk, one ``up`` of two robots:

- each robot's stand-in asks the shared planner on ``/<robot>/plan_request`` and hears only its own answers,
  once each, also for stamps both robots ask with;
- a session holding r1's certificate at the host's gate hears nothing of r2's and puts nothing into r2's
  namespace;
- ``fogiac robot revoke r2``: r2 unanswered within 10 s, its certificate closed at the host's gate after the
  handshake, r1 answered on, and no process on the host or here restarted;
- ``down`` leaves nothing on the host: no process in its namespace but its sshd, no folder.

As the other hosts tests do, fogiac's code is not pushed and the host runs it with this interpreter (which
has eclipse-zenoh); ROS 2 on the host is the stand-in of ``tests.support.ros2`` in its login environment.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.net.zenoh import tls
from fogiac.net.zenoh.config import TlsFiles
from fogiac.procs import free_port, poll
from fogiac.state import StackState
from tests.conftest import REPO
from tests.fleet.test_fleet_up_hosts import _host_processes, narrow_to_lab
from tests.fleet.test_fleet_up_local import _pids
from tests.fleet.test_fleet_zenoh_local import _answered, _as_robot, _files, _heard, _more, _went_quiet
from tests.net.zenoh.lab import ZenohLab
from tests.net.zenoh.test_zenoh_fleet import TYPE, _frame_id, _request, _text, tls_link
from tests.plugins.install import installed
from tests.provision.conftest import ros_skip_reason
from tests.provision.sshlab import LabHost, lab_skip_reason, ssh_lab
from tests.provision.test_zenoh_native import SYSTEM_PATH
from tests.support.procs import alive, alive_pids, started_pids
from tests.support.ros2 import standin_ros2

zenoh = pytest.importorskip("zenoh", reason="needs eclipse-zenoh (pip install 'fogiac[ros2]')")
pytest.importorskip("zenoh_ros2_sdk", reason="needs zenoh-ros2-sdk (pip install 'fogiac[ros2]')")
pytestmark = [pytest.mark.root, pytest.mark.zenoh,
              pytest.mark.skipif(bool(lab_skip_reason() or ros_skip_reason()),
                                 reason=lab_skip_reason() or ros_skip_reason() or "")]

NAME = "zhfleet"
STACK = f"{NAME}-dev"
ROBOTS = ("r1", "r2")


def _manifest(path: Path, host: LabHost, key: Path, ports: dict[str, int]) -> Path:
    robots = "".join(f'  - {{name: {r}, zenoh_router: "tcp/127.0.0.1:{port}"}}\n' for r, port in ports.items())
    path.write_text(f"""name: {NAME}
ros: {{distro: jazzy}}
cloud:
  provider: hosts
  runtime: native
  hosts:
    - {{name: {host.name}, address: {host.address}, user: root, key: {key}}}
robots:
{robots}nodes:
  - name: planner
    machine: t3.micro
    host: {host.name}
    command: [bash, -c, 'exec {sys.executable} -m tests.net.zenoh.echonode "${{FOGIAC_ZENOH_ROUTER##*:}}"
              --request /plan_request --reply /plan_result --delay 0.3']
    env: {{PYTHONPATH: "{REPO}", RUST_LOG: error}}
    topics: {{in: [/plan_request], out: [/plan_result]}}
""")
    return path


def test_a_ros2_fleet_on_a_lab_host_is_served_revoked_and_goes(tmp_path: Path, _state_dir: Path,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    runner = CliRunner()
    stack = StackState(STACK)
    ports = {robot: free_port() for robot in ROBOTS}
    login = {"PATH": f"{standin_ros2(tmp_path / 'ros2')}:{SYSTEM_PATH}"}  # ROS 2 as the host's admins set it up
    with ssh_lab(tmp_path / "lab", 1, env=login) as ((host,), key), \
            installed(tmp_path / "verb", "robotverb", {"fogiac.commands": {"robot": "fogiac.cli.robots"}}), \
            ZenohLab(tmp_path / "robots") as lab:
        (tmp_path / "robots").mkdir()
        base = host.base_dir / STACK
        narrow_to_lab(monkeypatch, base)
        manifest = _manifest(tmp_path / "fogiac.yaml", host, key, ports)
        pids: list[int] = []
        try:
            up = runner.invoke(app, ["up", str(manifest), "--yes"])
            assert up.exit_code == 0, up.output
            assert "<-> robots r1, r2" in up.output, up.output
            pids = started_pids(_state_dir)
            fleet = next(base.glob("**/zenoh-fleet.json"))
            assert fleet.stat().st_mode & 0o777 == 0o600  # written on the host over SSH, private there
            doc = json.loads(fleet.read_text())
            assert {r: v["common_name"] for r, v in doc["robots"].items()} == {
                r: tls.edge_name(STACK, r) for r in ROBOTS}
            assert doc["revoked"] == []
            on_host, host_pids = _host_processes(host), _pids(base)
            assert set(started_pids(base)) <= on_host  # the host's services run in its own namespace
            (edge1,) = [e for e in stack.get(StackState.EDGES) if e["name"] == "r1"]
            gate = edge1["relays"][host.name]
            assert gate.startswith(f"{host.address}:"), gate  # each robot's edge router dials the host itself

            outs = {r: lab.node(r, port, pub=(f"/{r}/plan_request=Header",), sub=(f"/{r}/plan_result=Header",))
                    for r, port in ports.items()}
            for robot, out in outs.items():
                assert poll(lambda o=out, r=robot: _answered(o, r) >= 5 or None, timeout=90), \
                    f"{robot} was never answered"

            # r1's certificate at the host's gate: nothing of r2's heard, nothing put into r2's namespace.
            attacker = _as_robot(stack, "r1", gate)
            stolen: list[str] = []
            mine: list[str] = []
            try:
                attacker.declare_subscriber("**", lambda s: stolen.append(_text(s.payload.to_bytes())))
                attacker.declare_subscriber(f"0/r1/plan_result/{TYPE}",
                                            lambda s: mine.append(_frame_id(s.payload.to_bytes())))
                time.sleep(1)
                for n in range(5):
                    attacker.put(f"0/r2/plan_result/{TYPE}", _request(n, "forged by r1"))
                    attacker.put(f"0/r2/plan_request/{TYPE}", _request(n, "forged by r1"))
                    attacker.put(f"0/r1/plan_request/{TYPE}", _request(5000 + n, "r1 asks"))  # its own: allowed
                    time.sleep(0.1)
                assert poll(lambda: len(mine) >= 5 or None, timeout=30), "r1's own requests were not answered"
                _more(outs, ("r2",), count=5)  # r2 heard on meanwhile: anything forged had time to reach it
            finally:
                attacker.close()
            assert set(mine) == {"r1 asks"}  # the link carried r1's own traffic through the gate
            assert not [t for t in stolen if "/r2/" in t or "r2 asks" in t], stolen
            assert not [e for e in _heard(outs["r2"], "r2") if "forged" in e["text"]]
            for robot, out in outs.items():  # each answer its own, once, though both robots ask with equal stamps
                got = _heard(out, robot)
                assert all(e["text"].startswith(f"/{robot}/plan_request #") for e in got), got
                assert len({e["seq"] for e in got}) == len(got), f"{robot} was answered twice"
            assert {e["seq"] for e in _heard(outs["r1"], "r1")} & {e["seq"] for e in _heard(outs["r2"], "r2")}

            # Revoked: r2 unanswered within 10 s, refused at the host's gate; r1 answered on; nothing restarted.
            edge_before = _pids(stack.edge)
            cut = time.monotonic()
            revoked = runner.invoke(app, ["robot", "revoke", "r2", str(manifest)])
            assert revoked.exit_code == 0, revoked.output
            assert json.loads(fleet.read_text())["revoked"] == ["r2"]

            took = _went_quiet(outs["r2"], "r2", cut)
            r2_files: TlsFiles = _files(stack, "r2")
            assert tls_link(gate, r2_files, ca=r2_files.ca, silent_s=5) == "closed"
            assert tls_link(gate, _files(stack, "r1"), ca=r2_files.ca, silent_s=1) == "open"  # r1's still let in
            r2_count = _answered(outs["r2"], "r2")
            _more(outs, ("r1",))
            assert _answered(outs["r2"], "r2") == r2_count
            assert _host_processes(host) == on_host and _pids(base) == host_pids
            assert _pids(stack.edge) == edge_before
            status = runner.invoke(app, ["status", str(manifest), "--json"])
            assert status.exit_code == 0, status.output
            rows: dict[str, Any] = {row["robot"]: row for row in json.loads(status.output)["robots"]}
            assert (rows["r1"]["revoked"], rows["r2"]["revoked"]) == (False, True)
            print(f"r2 unanswered {took:.1f} s after revoke")
        finally:
            down = runner.invoke(app, ["down", str(manifest), "--yes"])
        assert down.exit_code == 0, down.output
        assert _host_processes(host) == set(), "down left processes on the host"
        assert not base.exists()
    assert pids and [pid for pid in pids if alive(pid)] == []
    assert alive_pids(_state_dir) == []
