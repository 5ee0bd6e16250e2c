"""Issue 34, ROS 2 on ``local``: ``fogiac up`` deploys a fleet over Zenoh, each robot its own edge router,
certificate and namespace, one shared planner behind fogiac's fleet process.

One deployment, one test (its steps share the setup): three robots, each a zenoh-ros2-sdk stand-in on its own
edge router asking on ``/<robot>/plan_request`` and hearing on ``/<robot>/plan_result``, and a shared stand-in
planner in one sandbox answering the plain ``/plan_request`` on ``/plan_result`` late (0.3 s, so requests of
equal stamps from several robots are in flight at once). What ``up`` must have built and what must hold:

- the sandbox's fleet file (0600) beside its router's certificates: each robot by its certificate's name and
  router id, the planner's pair with the robots it serves; one supervised edge router per robot (``...@r1``);
- every request answered exactly once and to its own robot only, equal stamps from all three robots included,
  and raw requests with one stamp from r1 and r2 back to back each answered to its sender;
- a session holding r1's certificate, dialing the cloud router itself (past r1's own edge router, whose rules
  a robot could change), is refused r2's topics both ways: it hears none of r2's replies and what it puts in
  r2's namespace reaches neither the planner nor r2; its own request is answered (the link carried it);
- ``fogiac robot revoke r3``: r3 unanswered within 10 s, and r3's certificate refused at every host's router
  (a TLS link with it closed after the handshake, a Zenoh session with it unable to open), while r1 and r2
  are answered on, every request of theirs until r3 is restored; no process restarted (every pid kept); ``restore``: answered again;
- r3 dropped from ``robots:`` and ``up``: only its edge processes stop; added back and ``up``: only its start
  again, it is answered; the sandbox's processes keep their pids throughout; ``status`` shows each robot's
  link up and only its own namespaced topics, with requests served; ``down`` leaves nothing.

In the same deployment a per-robot SLAM-like stand-in (``serve: per_robot``, :mod:`tests.net.zenoh.slamnode`,
in a sandbox of its own) counts the scans it sees: ``up`` runs one instance per robot (``node-slam@r1``..., each
its own pid, ``--ros-args -r __ns:=/r1 -r /scan:=/r1/scan ...``) and no fleet process for it; every robot
publishes ``/<robot>/scan`` and hears on ``/<robot>/slam/count`` only its own instance's answers, and each
instance's state (its log) counts only its own robot's scans; r1's certificate at that sandbox's router reaches
neither r2's instance (scans put in r2's namespace are never counted) nor its answers; r3 revoked hears nothing
from its instance; dropped, only ``node-slam@r3`` stops there, added back, only it starts again.
"""

from __future__ import annotations

import json
import os
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
from tests.fleet.test_fleet_up_local import _pids
from tests.net.zenoh.lab import ZenohLab
from tests.net.zenoh.test_zenoh_fleet import (
    TYPE,
    _frame_id,
    _probe,
    _request,
    _text,
    ask_with_one_stamp,
    replies,
    tls_link,
)
from tests.plugins.install import installed
from tests.support.procs import alive, alive_pids, started_pids
from tests.support.ros2 import standin_ros2

zenoh = pytest.importorskip("zenoh", reason="needs eclipse-zenoh (pip install 'fogiac[ros2]')")
pytest.importorskip("zenoh_ros2_sdk", reason="needs zenoh-ros2-sdk (pip install 'fogiac[ros2]')")
pytestmark = pytest.mark.zenoh

NAME = "zfleet"
STACK = f"{NAME}-dev"
ROBOTS = ("r1", "r2", "r3")


@pytest.fixture(autouse=True)
def _ros2_on_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The sandbox is this machine: ROS 2 (a stand-in, see tests.support.ros2) in its login environment."""
    monkeypatch.setenv("PATH", f"{standin_ros2(tmp_path / 'ros2')}:{os.environ['PATH']}")


def _manifest(path: Path, ports: dict[str, int], slam_log: Path) -> None:
    robots = "".join(f'  - {{name: {r}, zenoh_router: "tcp/127.0.0.1:{port}"}}\n' for r, port in ports.items())
    path.write_text(f"""name: {NAME}
ros: {{distro: jazzy}}
cloud: {{provider: local, runtime: native}}
robots:
{robots}nodes:
  - name: planner
    machine: t3.micro
    command: [bash, -c, 'exec {sys.executable} -m tests.net.zenoh.echonode "${{FOGIAC_ZENOH_ROUTER##*:}}"
              --request /plan_request --reply /plan_result --delay 0.3']
    env: {{PYTHONPATH: "{REPO}", RUST_LOG: error}}
    topics: {{in: [/plan_request], out: [/plan_result]}}
  - name: slam
    machine: t3.micro
    command: [{sys.executable}, -m, tests.net.zenoh.slamnode, --log, "{slam_log}"]
    env: {{PYTHONPATH: "{REPO}", RUST_LOG: error}}
    topics: {{in: [/scan], out: [/slam/count]}}
    serve: per_robot
""")


def _files(stack: StackState, robot: str) -> TlsFiles:
    """``robot``'s own certificate and key, as ``up`` issued them, and the stack's CA."""
    folder = stack.edge / "zenoh"
    return TlsFiles(ca=str(folder / "ca.pem"), cert=str(folder / f"edge-{robot}.pem"),
                    key=str(folder / f"edge-{robot}.key"))


def _as_robot(stack: StackState, robot: str, address: str, *, timeout_ms: int = 10000) -> Any:
    """A Zenoh session holding ``robot``'s own certificate (as ``up`` issued it), dialing the cloud router."""
    folder = stack.edge / "zenoh"
    config = {"mode": "client", "connect": {"endpoints": [f"tls/{address}"], "timeout_ms": timeout_ms},
              "scouting": {"multicast": {"enabled": False}},
              "transport": {"link": {"tls": {
                  "root_ca_certificate": str(folder / "ca.pem"), "enable_mtls": True, "verify_name_on_connect": True,
                  "connect_certificate": str(folder / f"edge-{robot}.pem"),
                  "connect_private_key": str(folder / f"edge-{robot}.key")}}}}
    return zenoh.open(zenoh.Config.from_json5(json.dumps(config)))


def _heard(out: Path, robot: str, topic: str = "plan_result") -> list[dict[str, Any]]:
    """What ``robot``'s stand-in received on ``/<robot>/<topic>``."""
    return [e for e in replies(out) if e["topic"] == f"/{robot}/{topic}"]


def _answered(out: Path, robot: str) -> int:
    return len(_heard(out, robot))


def _counted(slam_log: Path, robot: str) -> list[dict[str, Any]]:
    """What ``robot``'s SLAM instance counted (its own log, one line per message it saw)."""
    path = slam_log / f"{robot}.jsonl"
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


def _own_instances(outs: dict[str, Path], slam_log: Path, robots: tuple[str, ...]) -> None:
    """Each robot heard its own instance only, and each instance counted its own robot's scans only."""
    for robot in robots:
        counts = [e["text"] for e in _heard(outs[robot], robot, "slam/count")]
        assert counts and all(t.startswith(f"/{robot}|") and f"|/{robot}/scan #" in t for t in counts), counts
        state = _counted(slam_log, robot)
        assert state and all(e["frame_id"].startswith(f"/{robot}/scan #") and f"/{robot}/scan/" in e["key"]
                             for e in state), state


def _went_quiet(out: Path, robot: str, cut: float) -> float:
    """Seconds from ``cut`` (the revoke) until ``robot`` heard no answer for 2 s; it must be under 10."""

    def quiet() -> bool | None:
        count = _answered(out, robot)
        time.sleep(2)
        return True if _answered(out, robot) == count else None

    assert poll(quiet, timeout=15)
    took = time.monotonic() - cut - 2
    assert took < 10, f"{robot} still answered {took:.1f} s after revoke"
    return took


def _more(outs: dict[str, Path], robots: tuple[str, ...], count: int = 5, timeout: float = 30) -> None:
    """Each of ``robots`` gets ``count`` more answers (from now)."""
    before = {r: _answered(outs[r], r) for r in robots}
    for robot in robots:
        assert poll(lambda r=robot: _answered(outs[r], r) >= before[r] + count or None, timeout=timeout), \
            f"{robot} was not answered on"


def test_up_deploys_a_ros2_fleet_over_zenoh(tmp_path: Path, _state_dir: Path) -> None:
    ports = {robot: free_port() for robot in ROBOTS}
    manifest = tmp_path / "fogiac.yaml"
    slam_log = tmp_path / "slam"
    _manifest(manifest, ports, slam_log)
    runner = CliRunner()
    stack = StackState(STACK)
    sandbox = _state_dir / STACK / "local" / "planner"
    slam_box = _state_dir / STACK / "local" / "slam"
    local = ["--target", "local"]
    pids: list[int] = []
    with installed(tmp_path / "verb", "robotverb", {"fogiac.commands": {"robot": "fogiac.cli.robots"}}), \
            ZenohLab(tmp_path) as lab:
        try:
            up = runner.invoke(app, ["up", str(manifest), *local, "--yes"])
            assert up.exit_code == 0, up.output
            assert "planner: relay 127.0.0.1:" in up.output and "<-> robots r1, r2, r3" in up.output
            pids = started_pids(_state_dir)
            fleet = sandbox / "certs" / "zenoh-fleet.json"
            assert fleet.stat().st_mode & 0o077 == 0
            doc = json.loads(fleet.read_text())
            assert {r: v["common_name"] for r, v in doc["robots"].items()} == {
                r: tls.edge_name(STACK, r) for r in ROBOTS}
            assert doc["revoked"] == [] and doc["shared"] == [
                {"node": "planner", "requests": ["/plan_request"], "replies": ["/plan_result"], "robots": list(ROBOTS)}]
            edge_routers = {p.stem for p in stack.edge.glob("zenoh-edge-router*.pid")}
            assert edge_routers == {f"zenoh-edge-router@{r}" for r in ROBOTS}
            # one SLAM instance per robot, each its own service and pid, and no fleet process for it
            slam_json = json.loads((slam_box / "certs" / "zenoh-fleet.json").read_text())
            assert slam_json["shared"] == [] and set(slam_json["robots"]) == set(ROBOTS)
            instances = {k: v for k, v in _pids(slam_box).items() if "node-slam" in k}
            assert sorted(Path(k).stem for k in instances) == [f"node-slam@{r}" for r in ROBOTS]
            assert len(set(instances.values())) == len(ROBOTS)
            assert not [k for k in _pids(slam_box) if "zenoh-fleet" in k]

            # Every robot's stand-in asks with the stamps every other uses; each hears only its own answers, once.
            outs = {r: lab.node(r, port, pub=(f"/{r}/plan_request=Header", f"/{r}/scan=Header"),
                                sub=(f"/{r}/plan_result=Header", f"/{r}/slam/count=Header"))
                    for r, port in ports.items()}
            for robot, out in outs.items():
                assert poll(lambda o=out, r=robot: _answered(o, r) >= 8 or None, timeout=90), \
                    f"{robot} was never answered"
                assert poll(lambda o=out, r=robot: len(_heard(o, r, "slam/count")) >= 8 or None, timeout=60), \
                    f"{robot}'s SLAM instance never answered it"
            # Raw requests with one stamp from r1 and r2 back to back, on their edge routers: each gets its own.
            probes = {r: _probe(ports[r]) for r in ("r1", "r2")}
            try:
                heard = ask_with_one_stamp(probes)

                # r1's certificate at the cloud router itself: refused r2's topics, both ways.
                (edge,) = [e for e in stack.get(StackState.EDGES) if e["name"] == "r1"]
                attacker = _as_robot(stack, "r1", edge["relays"]["planner"])
                at_slam = _as_robot(stack, "r1", edge["relays"]["slam"])  # r1 at the SLAM sandbox's router
                stolen: list[str] = []
                mine: list[str] = []
                forged_at_r2: list[str] = []
                try:
                    # its own session hands it its own puts back; only r2's messages (their frame ids) would be stolen
                    attacker.declare_subscriber("*/r2/**", lambda s: stolen.append(_text(s.payload.to_bytes())))
                    attacker.declare_subscriber("**", lambda s: stolen.append(_text(s.payload.to_bytes())))
                    at_slam.declare_subscriber("*/r2/**", lambda s: stolen.append(_text(s.payload.to_bytes())))
                    at_slam.declare_subscriber("**", lambda s: stolen.append(_text(s.payload.to_bytes())))
                    attacker.declare_subscriber(f"0/r1/plan_result/{TYPE}",
                                                lambda s: mine.append(_frame_id(s.payload.to_bytes())))
                    probes["r2"].declare_subscriber(f"0/r2/plan_result/{TYPE}", lambda s: forged_at_r2.append(
                        _frame_id(s.payload.to_bytes())) if b"forged" in s.payload.to_bytes() else None)
                    time.sleep(1)
                    for n in range(10):
                        attacker.put(f"0/r2/plan_result/{TYPE}", _request(n, "forged by r1"))  # into r2's replies
                        attacker.put(f"0/r2/plan_request/{TYPE}", _request(n, "forged by r1"))  # as r2, to the planner
                        attacker.put(f"0/plan_request/{TYPE}", _request(n, "forged by r1"))  # past the fleet process
                        attacker.put(f"0/r1/plan_request/{TYPE}", _request(5000 + n, "r1 asks"))  # its own: allowed
                        at_slam.put(f"0/r2/scan/{TYPE}", _request(n, "forged by r1"))  # to r2's SLAM instance
                        at_slam.put(f"0/scan/{TYPE}", _request(n, "forged by r1"))  # bare, to any instance
                        time.sleep(0.1)
                    assert poll(lambda: len(mine) >= 10 or None, timeout=30), "r1's own requests were not answered"
                    _more(outs, ("r2",), count=10)  # r2 heard on meanwhile: anything forged had time to reach it
                finally:
                    attacker.close()
                    at_slam.close()
            finally:
                for probe in probes.values():
                    probe.close()
            for robot, got in heard.items():  # r1's own requests of the next step come back to r1 too
                assert all(frame.startswith(f"{robot} asks") for frame, _ in got), got
                assert sorted(g for g in got if g[1] == (777, 0)) == [(f"{robot} asks {n}", (777, 0)) for n in range(5)]
            assert stolen and not [t for t in stolen if "r2 asks" in t or "/r2/" in t], stolen  # nothing of r2's
            assert set(mine) == {"r1 asks"} and forged_at_r2 == []
            assert not [e for e in replies(outs["r2"]) if "forged" in e["text"]]
            assert not [e for r in ROBOTS for e in _counted(slam_log, r) if "forged" in e["frame_id"]]
            _own_instances(outs, slam_log, ROBOTS)
            for robot, out in outs.items():
                got = _heard(out, robot)
                assert all(e["text"].startswith(f"/{robot}/plan_request #") for e in got), got
                assert all(e["text"].endswith(f"@{e['seq']}.0") for e in got), "a robot saw a stamp it did not send"
                assert len({e["seq"] for e in got}) == len(got), f"{robot} was answered twice"
            seqs = [{e["seq"] for e in _heard(out, robot)} for robot, out in outs.items()]
            assert seqs[0] & seqs[1] & seqs[2], "no stamp was asked by every robot"

            # Revoked: r3 unanswered within 10 s, its certificate refused; r1 and r2 answered on; no restart.
            host_before, edge_before, slam_before = _pids(sandbox), _pids(stack.edge), _pids(slam_box)
            since = {r: max(e["seq"] for e in _heard(outs[r], r)) for r in ("r1", "r2")}
            planner_child = (sandbox / "run" / "node-planner.child").read_text().split()[0]
            cut = time.monotonic()
            revoked = runner.invoke(app, ["robot", "revoke", "r3", str(manifest), *local])
            assert revoked.exit_code == 0, revoked.output
            assert json.loads(fleet.read_text())["revoked"] == ["r3"]

            took = _went_quiet(outs["r3"], "r3", cut)
            r3_count = _answered(outs["r3"], "r3")
            r3_slam = len(_heard(outs["r3"], "r3", "slam/count"))
            _more(outs, ("r1", "r2"))
            (edge3,) = [e for e in stack.get(StackState.EDGES) if e["name"] == "r3"]
            for host, address in edge3["relays"].items():  # its certificate refused at every host's TLS gate
                assert tls_link(address, _files(stack, "r3"), ca=_files(stack, "r3").ca, silent_s=5) == "closed", host
            with pytest.raises(zenoh.ZError):  # so a Zenoh session holding it cannot open
                _as_robot(stack, "r3", edge3["relays"]["planner"], timeout_ms=1500).close()
            _more(outs, ("r1", "r2"))
            assert _answered(outs["r3"], "r3") == r3_count
            assert len(_heard(outs["r3"], "r3", "slam/count")) == r3_slam  # nor its SLAM instance's answers
            assert _pids(sandbox) == host_before and _pids(stack.edge) == edge_before  # nothing restarted
            assert _pids(slam_box) == slam_before
            assert (sandbox / "run" / "node-planner.child").read_text().split()[0] == planner_child
            print(f"r3 unanswered {took:.1f} s after revoke")

            restored = runner.invoke(app, ["robot", "restore", "r3", str(manifest), *local])
            assert restored.exit_code == 0, restored.output
            _more(outs, ("r3", "r1"))
            for robot in ("r1", "r2"):  # while r3 was cut off and let back, none of their requests went unanswered
                seqs = {e["seq"] for e in _heard(outs[robot], robot)}
                assert sorted(set(range(since[robot], max(seqs) + 1)) - seqs) == [], f"{robot} lost requests"
            assert _pids(sandbox) == host_before and _pids(stack.edge) == edge_before

            # r3 dropped from robots: and up: only its edge processes stop; added back: only they start again.
            _manifest(manifest, {r: p for r, p in ports.items() if r != "r3"}, slam_log)
            dropped = runner.invoke(app, ["up", str(manifest), *local, "--yes"])
            assert dropped.exit_code == 0, dropped.output
            assert "robot r3: its edge router stopped" in dropped.output
            assert _pids(sandbox) == host_before
            assert _pids(stack.edge) == {k: v for k, v in edge_before.items() if "@r3" not in k}
            assert _pids(slam_box) == {k: v for k, v in slam_before.items() if "@r3" not in k}  # only r3's instance
            assert set(json.loads(fleet.read_text())["robots"]) == {"r1", "r2"}
            _more(outs, ("r1", "r2"), count=3)
            _manifest(manifest, ports, slam_log)
            again = runner.invoke(app, ["up", str(manifest), *local, "--yes"])
            assert again.exit_code == 0, again.output
            assert _pids(sandbox) == host_before
            edge_now = _pids(stack.edge)
            assert {k: v for k, v in edge_now.items() if "@r3" not in k} == {
                k: v for k, v in edge_before.items() if "@r3" not in k}
            assert {k for k in edge_now if "@r3" in k} == {k for k in edge_before if "@r3" in k}
            slam_now = _pids(slam_box)
            assert {k: v for k, v in slam_now.items() if "@r3" not in k} == {
                k: v for k, v in slam_before.items() if "@r3" not in k}
            assert {k for k in slam_now if "@r3" in k} == {k for k in slam_before if "@r3" in k}
            _more(outs, ("r3", "r1", "r2"), timeout=60)  # the stand-in on r3's router, which came back, asks on
            r3_back = len(_heard(outs["r3"], "r3", "slam/count"))
            assert poll(lambda: len(_heard(outs["r3"], "r3", "slam/count")) > r3_back or None, timeout=30), \
                "r3's new SLAM instance never answered it"
            _own_instances(outs, slam_log, ROBOTS)

            shown_last: list[str] = []

            def rows() -> dict[str, Any] | None:  # the edge routers and monitors write their figures every second
                shown = runner.invoke(app, ["status", str(manifest), *local, "--json"])
                assert shown.exit_code == 0, shown.output
                shown_last[:] = [shown.output]
                found = {r["robot"]: r for r in json.loads(shown.output)["robots"]}
                return found if all(found.get(r, {}).get("served") for r in ROBOTS) else None

            robot_rows = poll(rows, timeout=30)
            assert robot_rows is not None, "status never showed every robot served"
            for robot, row in robot_rows.items():  # each robot's own link and its namespaced topics
                mine = {f"/{robot}/{t}" for t in ("plan_request", "plan_result", "scan", "slam/count")}
                assert row["links_up"] == 2 and row["topics"] and set(row["topics"]) <= mine, row
            assert all(f'"slam@{r}"' in shown_last[0] for r in ROBOTS), shown_last  # each instance by its name
            logs = runner.invoke(app, ["logs", "slam@r2", str(manifest)])
            assert logs.exit_code == 0 and "slam up in /r2: /r2/scan -> /r2/slam/count" in logs.output, logs.output
        finally:
            down = runner.invoke(app, ["down", str(manifest), *local, "--yes"])
    assert down.exit_code == 0, down.output
    assert pids and [pid for pid in pids if alive(pid)] == []
    assert alive_pids(_state_dir) == []
    assert not (_state_dir / STACK / "local").exists()
