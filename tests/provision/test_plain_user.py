"""The native runtime as a new user meets it on a lab machine: a plain login with sudo, the system python3.

A namespace host with its own sshd; fogiac logs in as an ordinary account (not root) whose home
is fogiac's only folder, pushes its code, and builds one virtual environment over Debian's
/usr/bin/python3 (which has rospy and nothing else fogiac needs) holding fogiac's requirements
(the relay's cloud end imports them) and both shipped workloads' (OMPL, torch). ``fogiac up
--target hosts`` then answers a motion-planning request and a depth image through the relay from
the robot's master, and a second ``up`` installs nothing and restarts nothing.

Like a lab with a package mirror, the host's sessions point pip at this machine's: its index
(/opt/pypi) and the wheels it lacks (``.ci/lab-wheels.sh``; torch's CPU wheel from /opt/wheels), and pip
leaves byte-compiling to Python (``sshlab.PIP_LEAVES_COMPILING``).
"""

from __future__ import annotations

import json
import os
import pwd
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.procs import free_port
from tests.conftest import REPO
from tests.provision.conftest import ros_skip_reason
from tests.provision.sshlab import PIP_LEAVES_COMPILING, lab_skip_reason, plain_user, ssh_lab
from tests.targets.test_local import CLIENT as PLAN_CLIENT

WHEELS = Path("/var/cache/fogiac-ci/lab-wheels")
GRASP_CLIENT = REPO / "tests" / "workloads" / "grasp_planning" / "grasp_ros_client.py"
MIRROR = {"PIP_INDEX_URL": "file:///opt/pypi/simple", "PIP_FIND_LINKS": f"{WHEELS} /opt/wheels",
          **PIP_LEAVES_COMPILING}


def _why_not() -> str | None:
    reason = lab_skip_reason() or ros_skip_reason()
    if reason:
        return reason
    if not (WHEELS / ".stamp").exists() or not list(Path("/opt/wheels").glob("torch-2.13.0*.whl")):
        return f"needs the lab's package mirror ({WHEELS}: bash .ci/lab-wheels.sh; torch's wheel in /opt/wheels)"
    if not Path("/usr/bin/sudo").exists():
        return "needs sudo (apt-get install sudo): the lab user has it"
    if subprocess.run(["/usr/bin/python3", "-c", "import numpy"], capture_output=True).returncode == 0:
        return "the system python3 has numpy already: nothing would show the venv is used"
    return None


pytestmark = [pytest.mark.root, pytest.mark.ros, pytest.mark.skipif(_why_not() is not None, reason=_why_not() or "")]


def ask_grasp(edge_port: int, *, cwd: Path) -> dict:
    """The robot's side: one depth image published on the edge master at ``edge_port``; the grasp that answers."""
    from workloads.grasp_planning.data import TEST_SEED, bench_scene

    scene = bench_scene(TEST_SEED + 7, height=240, width=320)
    np.save(cwd / "depth.npy", scene.depth)
    intr = scene.intr
    env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{edge_port}", "ROS_HOSTNAME": "127.0.0.1",
           "PYTHONPATH": str(REPO)}
    grasped = subprocess.run(
        [sys.executable, str(GRASP_CLIENT), str(cwd / "depth.npy"), str(intr.fx), str(intr.fy),
         str(intr.cx), str(intr.cy), "120", "32FC1"],
        env=env, capture_output=True, text=True, timeout=180, cwd=cwd)
    assert grasped.returncode == 0, grasped.stderr[-3000:]
    (grasp,) = [json.loads(line) for line in grasped.stdout.splitlines() if line.startswith("{")]
    return grasp


def _uids(pids: list[int]) -> set[int]:
    found = set()
    for pid in pids:
        try:
            found.add(Path(f"/proc/{pid}").stat().st_uid)
        except OSError:
            pass
    return found


def _tails(base: Path) -> str:
    return "\n".join(f"--- {log.name}\n" + "\n".join(log.read_text(errors="replace").splitlines()[-15:])
                     for log in sorted((base / "run").glob("*.log")))


def test_both_workloads_answer_through_the_relay_from_a_plain_users_native_host(tmp_path: Path,
                                                                                 _state_dir: Path) -> None:
    edge_port = free_port()
    runner = CliRunner()
    with ssh_lab(tmp_path / "lab", 1, env=MIRROR) as (hosts, key), plain_user(key) as (user, home):
        (host,) = hosts
        manifest = tmp_path / "fogiac.yaml"
        manifest.write_text(f"""name: plainlab
cloud:
  provider: hosts
  runtime: native
  hosts:
    - {{name: lab1, address: {host.address}, user: {user}, key: {key}}}
edge: {{ros_master: "http://127.0.0.1:{edge_port}"}}
nodes:
  - name: planner
    machine: t3.small
    workload: motion_planning
    topics: {{in: [/motion_planning/request], out: [/motion_planning/path, /motion_planning/compute_time]}}
  - name: grasp
    machine: t3.small
    workload: grasp_planning
    topics: {{in: [/depth/image, /depth/camera_info], out: [/grasp, /grasp/quality, /grasp/compute_time]}}
""")
        try:
            up = runner.invoke(app, ["up", str(manifest), "--yes", "--start-edge-master"])
            assert up.exit_code == 0, up.output
            base = home / ".fogiac" / "plainlab-dev" / "lab1"
            install_log = base / "run" / "venv-install.log"
            assert "Successfully installed" in install_log.read_text() and "torch-2.13.0" in install_log.read_text()
            (venv_python,) = base.glob("venv/*/bin/python")
            for name in ("node-planner", "node-grasp", "relay-cloud"):
                script = (base / "services" / f"{name}.sh").read_text()
                assert f"{venv_python.parent}/python" in script.replace("'", ""), (name, script)
            services = ("node-planner", "node-grasp", "relay-cloud", "ros-master")
            children = [json.loads((base / "run" / f"{s}.state").read_text())["child"] for s in services]
            assert _uids(children) == {pwd.getpwnam(user).pw_uid}, "every service runs as the login user"
            assert set(children) <= set(host.ns.pids()), _tails(base)

            env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{edge_port}", "ROS_HOSTNAME": "127.0.0.1",
                   "PYTHONPATH": str(REPO)}
            planned = subprocess.run([sys.executable, "-c", PLAN_CLIENT], env=env, capture_output=True, text=True,
                                     timeout=240, cwd=tmp_path)
            assert planned.returncode == 0, planned.stderr[-3000:]
            answer = json.loads(planned.stdout.strip().splitlines()[-1])
            assert answer["solved"] and answer["poses"] >= 2 and answer["free"], answer

            grasp = ask_grasp(edge_port, cwd=tmp_path)
            assert "error" not in grasp and 0.0 <= grasp["quality"] <= 1.0, grasp

            log_before = install_log.stat().st_mtime_ns
            again = runner.invoke(app, ["up", str(manifest), "--yes"])
            assert again.exit_code == 0, again.output
            assert "no changes" in again.output, again.output
            assert install_log.stat().st_mtime_ns == log_before, "the second up installed nothing"
            assert [json.loads((base / "run" / f"{s}.state").read_text())["child"] for s in services] == children
        finally:
            down = runner.invoke(app, ["down", str(manifest), "--yes"])
            assert down.exit_code == 0, down.output
