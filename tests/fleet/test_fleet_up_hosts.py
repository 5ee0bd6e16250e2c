"""Issue 34, ROS 1 on ``hosts``: ``fogiac up`` deploys a fleet to a lab machine reached over real SSH.

One namespace lab host with its own sshd (``tests/provision/sshlab.py``) runs the stack's master, the relay's
cloud end and the shared stand-in planner of ``test_fleet_up_local``; each robot is a real master of its own on
this machine (``--start-edge-master``) with its own client process and its own supervised edge end dialing the
host. One walk, one ``up`` of two robots, in the order an operator meets it:

- ``fogiac plan`` of the manifest with a third robot names the robot's certificate, access rules and edge
  process and nothing else (no host changed), and ``up`` then issues its certificate (its key 0600), rewrites
  the host's access file over SSH (0600 there) and starts its edge end: every process on the host keeps its
  pid, and so do the other robots' edge ends.
- All three robots' requests, stamped alike, are each answered exactly once and to the robot that asked;
  arm2's own namespace reaches arm2 alone.
- ``fogiac robot revoke arm3`` cuts arm3's link within 10 s while arm1 and arm2 stay linked, with no process
  restarted on the host; ``status`` says arm3 is revoked. Dropped from the manifest, ``plan`` names it alone and
  ``up`` stops its edge end only, the host's processes still keeping their pids.
- ``down`` leaves nothing: no process in the host's namespace but its sshd, no folder, no edge process here.

As the other hosts tests do, fogiac's code is not pushed (the namespaces share this checkout, which other work
may edit meanwhile) and the host runs it with this interpreter: the hosts target's access is narrowed to that
for the test, everything else is the real ``fogiac up``, ``plan``, ``robot revoke`` and ``down``.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.certs import edge_identity, edge_role
from fogiac.cli import app
from fogiac.procs import free_port
from fogiac.provision import SshAccess
from fogiac.state import StackState, read_json
from fogiac.targets.hosts.target import HostsTarget
from tests.docs.blocks import REPO, blocks, normalise
from tests.fleet.fleet_support import wait as _wait
from tests.fleet.test_fleet_up_local import PLANNER, REQUESTS, _clients, _pids
from tests.plugins.install import installed
from tests.provision.conftest import ros_skip_reason
from tests.provision.sshlab import LabHost, lab_skip_reason, ssh_lab
from tests.support.procs import alive, alive_pids, started_pids

pytestmark = [pytest.mark.root, pytest.mark.ros,
              pytest.mark.skipif(bool(lab_skip_reason() or ros_skip_reason()),
                                 reason=lab_skip_reason() or ros_skip_reason() or "")]

NAME = "hfleet"
STACK = f"{NAME}-dev"


def _manifest(path: Path, host: LabHost, key: Path, ports: Mapping[str, int], planner: Path) -> Path:
    robots = "".join(f'  - {{name: {name}, ros_master: "http://127.0.0.1:{port}"}}\n' for name, port in ports.items())
    path.write_text(f"""name: {NAME}
cloud:
  provider: hosts
  hosts:
    - {{name: {host.name}, address: {host.address}, user: root, key: {key}}}
robots:
{robots}nodes:
  - name: planner
    machine: t3.micro
    host: {host.name}
    command: [{sys.executable}, "{planner}"]
    topics: {{in: [/plan/request], out: [/plan/reply, /arm2/status]}}
""")
    return path


def narrow_to_lab(monkeypatch: pytest.MonkeyPatch, base: Path) -> None:
    """The hosts target's access as these tests narrow it: the lab host's folder ``base``, this interpreter,
    fogiac's code not pushed (the namespaces share this checkout)."""
    real_access = HostsTarget.access

    def lab_access(self: HostsTarget, plan: object, **kwargs: object) -> dict[str, SshAccess]:
        return {n: replace(a, base_dir=str(base), python=sys.executable, ship_code=False)
                for n, a in real_access(self, plan, **kwargs).items()}  # type: ignore[arg-type]

    monkeypatch.setattr(HostsTarget, "access", lab_access)


def _host_processes(host: LabHost) -> set[int]:
    """Every process in the host's namespace but its sshd and what runs in an SSH session (a command of
    provisioning still exiting): fogiac's services are detached from the session that started them."""
    found = set()
    for pid in host.ns.pids():
        try:
            ancestor = pid
            while ancestor > 1 and not Path(f"/proc/{ancestor}/comm").read_text().startswith("sshd"):
                ancestor = int(Path(f"/proc/{ancestor}/stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue  # gone meanwhile: not a service
        if ancestor <= 1:
            found.add(pid)
    return found


def _connected(stack: StackState, host: str, robot: str) -> bool | None:
    return (read_json(stack.edge / f"relay-edge-{host}@{robot}.stats.json") or {}).get("connected")


def test_a_fleet_on_a_lab_host_grows_is_revoked_and_goes(tmp_path: Path, _state_dir: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    runner = CliRunner()
    stack = StackState(STACK)
    planner = tmp_path / "planner.py"
    planner.write_text(PLANNER)
    two = {name: free_port() for name in ("arm1", "arm2")}
    three = {**two, "arm3": free_port()}
    with ssh_lab(tmp_path / "lab", 1) as ((host,), key), \
            installed(tmp_path / "verb", "robotverb", {"fogiac.commands": {"robot": "fogiac.cli.robots"}}):
        base = host.base_dir / STACK
        narrow_to_lab(monkeypatch, base)
        manifest = _manifest(tmp_path / "fogiac.yaml", host, key, two, planner)
        try:
            up = runner.invoke(app, ["up", str(manifest), "--yes", "--start-edge-master"])
            assert up.exit_code == 0, up.output
            assert f"{host.name}: relay {host.address}:" in up.output and "<-> robots arm1, arm2" in up.output
            _wait("both robots linked", lambda: all(_connected(stack, host.name, r) for r in two), 60)
            on_host, host_pids, edge_pids = _host_processes(host), _pids(base), _pids(stack.edge)
            assert set(started_pids(base)) <= on_host  # the host's services run in its own namespace

            # arm3 joins: the plan names its certificate, access rules and edge process, and no host.
            _manifest(manifest, host, key, three, planner)
            shown = runner.invoke(app, ["plan", str(manifest), "--detailed-exitcode"])
            assert shown.exit_code == 2, shown.output
            lines = [line.strip() for line in shown.output.splitlines()]
            assert "+ robot arm3 (ROS master http://127.0.0.1:{})".format(three["arm3"]) in lines, shown.output
            assert f"certificate {edge_identity(STACK, 'arm3')} (issued by the stack's CA)" in lines
            assert "Plan: 0 to add, 0 to change, 0 to destroy. Robots: 1 to add, 0 to change, 0 to remove." in lines
            assert "hosts:" not in lines and "nodes:" not in lines, shown.output

            grown = runner.invoke(app, ["up", str(manifest), "--yes", "--start-edge-master"])
            assert grown.exit_code == 0, grown.output
            key_file = stack.certs / f"{edge_role(STACK, 'arm3')}.key"
            assert key_file.stat().st_mode & 0o777 == 0o600  # its certificate, issued here, never readable by others
            access = base / "certs" / "fleet.json"
            assert access.stat().st_mode & 0o777 == 0o600  # rewritten on the host over SSH, private there too
            rules = json.loads(access.read_text())
            assert {name: r["identity"] for name, r in rules["robots"].items()} == {
                name: edge_identity(STACK, name) for name in three}
            assert _host_processes(host) == on_host and _pids(base) == host_pids  # nothing on the host restarted
            edge_now = _pids(stack.edge)
            assert {k: v for k, v in edge_now.items() if "arm3" not in k} == edge_pids  # nor the other robots' ends
            assert {k for k in edge_now if "arm3" in k} == {f"relay-edge-{host.name}@arm3.pid", "edge-master@arm3.pid"}

            reports = _clients(three, tmp_path)
            for robot, report in reports.items():  # stamped alike by every robot, each answered once, to it alone
                assert sorted(report["got"]) == sorted(f"{robot}:{i}" for i in range(REQUESTS)), (robot, report)
            assert reports["arm2"]["status"] > 0 and reports["arm1"]["status"] == reports["arm3"]["status"] == 0

            revoked = runner.invoke(app, ["robot", "revoke", "arm3", str(manifest)])
            assert revoked.exit_code == 0, revoked.output
            shown_in_guide = [b for b in blocks(REPO / "docs" / "guides" / "fleet.md") if b.kind == "checked"
                              and b.field("test") == "tests/fleet/test_fleet_up_hosts.py"]
            assert [normalise(b.body) for b in shown_in_guide] == [normalise(revoked.output)]  # the guide shows it
            took = _wait("arm3's link cut", lambda: _connected(stack, host.name, "arm3") is False, 10)
            assert took < 10
            assert json.loads(access.read_text())["revoked"] == ["arm3"]
            assert _connected(stack, host.name, "arm1") and _connected(stack, host.name, "arm2")
            assert _host_processes(host) == on_host and _pids(base) == host_pids
            status = runner.invoke(app, ["status", str(manifest), "--json"])
            assert status.exit_code == 0, status.output
            rows = {row["robot"]: row for row in json.loads(status.output)["robots"]}
            assert {name: (row["revoked"], row["links_up"]) for name, row in rows.items()} == {
                "arm1": (False, 1), "arm2": (False, 1), "arm3": (True, 0)}  # revoked, not merely down

            # arm3 leaves the manifest: the plan names it alone, up stops only its edge end and forgets it was
            # revoked; the host's file lists the two others, and still nothing on the host restarts.
            _manifest(manifest, host, key, two, planner)
            shown = runner.invoke(app, ["plan", str(manifest), "--detailed-exitcode"])
            assert shown.exit_code == 2 and "Robots: 0 to add, 0 to change, 1 to remove." in shown.output, shown.output
            dropped = runner.invoke(app, ["up", str(manifest), "--yes"])
            assert dropped.exit_code == 0 and "robot arm3: its edge end stopped" in dropped.output, dropped.output
            assert _pids(stack.edge) == edge_pids and stack.get(StackState.REVOKED) is None
            assert (set(json.loads(access.read_text())["robots"]), json.loads(access.read_text())["revoked"]) == (
                set(two), [])
            assert _host_processes(host) == on_host and _pids(base) == host_pids
        finally:
            down = runner.invoke(app, ["down", str(manifest), "--yes"])
        assert down.exit_code == 0, down.output
        assert _host_processes(host) == set(), "down left processes on the host"
        assert not base.exists()
    assert alive_pids(_state_dir) == []
    assert [pid for pid in started_pids(_state_dir) if alive(pid)] == []
