"""Native hosts get their workloads' requirements: a venv over the system's python3 and rospy.

A namespace host with its own sshd runs the grasp-planning node on Debian's /usr/bin/python3
(which has rospy but no numpy or torch): provisioning builds a virtual environment with the
workload's pinned requirements, the node registers with the host's master, and a second run
installs nothing. The namespaces have no route to the internet: like a lab with a local package
mirror, their sessions set PIP_INDEX_URL to this machine's package folder (pip finds torch there too), and
pip leaves byte-compiling to Python (``sshlab.PIP_LEAVES_COMPILING``).
"""

from __future__ import annotations

import os
import subprocess
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from fogiac.errors import ProvisionError
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Plan
from fogiac.provision import provision, teardown, venv
from fogiac.provision.local import LocalHost
from fogiac.targets.hosts.target import HOSTS
from tests.provision.conftest import make_workspace, ros_skip_reason
from tests.provision.sshlab import PIP_LEAVES_COMPILING, lab_skip_reason, ssh_lab

SYSTEM_PYTHON = "/usr/bin/python3"
WHEELS = Path("/var/cache/fogiac-ci/lab-wheels")  # the lab's mirror (.ci/lab-wheels.sh)


def _lab_plan(tmp_path: Path, host: Any, key: Path, *, name: str, nodes: str) -> tuple[Plan, dict[str, Any]]:
    """A native hosts-target plan on one namespace host as root, and its access for Debian's python3."""
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(f"""name: {name}
cloud:
  provider: hosts
  runtime: native
  hosts:
    - {{name: {host.name}, address: {host.address}, user: root, key: {key}}}
nodes:
{nodes}""")
    plan = compile_plan(load_manifest(manifest))
    return plan, {n: replace(a, base_dir=str(host.base_dir))
                  for n, a in HOSTS.access(plan, state_dir=tmp_path, python=SYSTEM_PYTHON).items()}


def _second_up_installs_nothing(plan: Plan, access: dict[str, Any], tmp_path: Path, *, health_timeout: float) -> None:
    again = provision(plan, hosts=access, state_dir=tmp_path, health_timeout=health_timeout)
    assert again.no_changes, [(s.name, s.status, s.detail) for s in again.hosts[0].steps]
    assert next(s for s in again.hosts[0].steps if s.name == "venv").status == "ok"


def test_a_python_without_venv_support_is_named_with_the_command(tmp_path: Path) -> None:
    fake = tmp_path / "python3"
    fake.write_text("#!/bin/sh\nexit 1\n")  # as Debian's python3 answers `import ensurepip` without python3-venv
    fake.chmod(0o755)
    host = LocalHost(name="lab1", base=str(tmp_path))
    with pytest.raises(ProvisionError, match=r"^lab1: .*/python3 cannot make virtual environments \(python3-venv "
                                             r"is missing\); run: sudo apt-get install -y python3-venv$"):
        venv.ensure(host, root=f"{tmp_path}/venv", marker=f"{tmp_path}/m", known="", reqs=("numpy",),
                    python=str(fake), allow_install=False, log=f"{tmp_path}/log")
    assert not (tmp_path / "venv").exists()


def test_requirements_come_from_the_recipes_pinned() -> None:
    reqs = venv.requirements(["grasp_planning", "motion_planning", "grasp_planning"])
    assert reqs[0] == "torch==2.13.0" and "ompl==2.0.1" in reqs and len(reqs) == len(set(reqs))
    assert venv.pins_digest(reqs, "python3") != venv.pins_digest(reqs[1:], "python3")


@pytest.mark.root
@pytest.mark.ros
@pytest.mark.skipif(bool(lab_skip_reason() or ros_skip_reason()), reason=lab_skip_reason() or ros_skip_reason() or "")
def test_grasp_workload_runs_on_the_system_python_in_a_venv_built_once(tmp_path: Path) -> None:
    if subprocess.run([SYSTEM_PYTHON, "-c", "import numpy"], capture_output=True).returncode == 0:
        pytest.skip("the system python3 has numpy already: nothing would show the venv is used")
    lab_env = {"PIP_INDEX_URL": "file:///opt/pypi/simple", **PIP_LEAVES_COMPILING}
    with ssh_lab(tmp_path / "lab", 1, env=lab_env) as (hosts, key):
        (host,) = hosts
        plan, access = _lab_plan(tmp_path, host, key, name="venvtest",
                                 nodes="  - {name: grasp, machine: t3.small, workload: grasp_planning}\n")
        try:
            first = provision(plan, hosts=access, state_dir=tmp_path, health_timeout=120)
            (outcome,) = first.hosts
            assert outcome.ok, outcome.error
            assert "venv" in outcome.changed and "services" in outcome.changed
            venv_step = next(s for s in outcome.steps if s.name == "venv")
            assert "torch==2.13.0" in venv_step.detail
            script = next(host.base_dir.glob("services/node-grasp.sh")).read_text()
            assert f"exec {host.base_dir}/venv/" in script and "/bin/python -m workloads.grasp_planning node" in script
            _second_up_installs_nothing(plan, access, tmp_path, health_timeout=120)
        finally:
            teardown(plan, hosts=access, state_dir=tmp_path)


LAUNCH_TALKER = """#!/usr/bin/env python3
import rospy
import shellingham
from std_msgs.msg import String

rospy.init_node("fog_talker")
pub = rospy.Publisher("/chatter", String, queue_size=1)
rate = rospy.Rate(5)
while not rospy.is_shutdown():
    pub.publish("shellingham " + shellingham.__version__)
    rate.sleep()
"""


def test_a_requirements_file_with_pip_options_is_refused_naming_the_line(tmp_path: Path) -> None:
    reqs = tmp_path / "requirements.txt"
    reqs.write_text("# the package's own\nshellingham==1.5.4  # shells\n\n--index-url http://elsewhere/simple\n")
    with pytest.raises(ProvisionError, match=rf"^{reqs}:4: --index-url: only package specifiers are allowed here; "
                                             "the host's pip settings choose the index$"):
        venv.file_requirements(str(reqs))
    reqs.write_text("# the package's own\nshellingham == 1.5.4  # shells\n\n")
    assert venv.file_requirements(str(reqs)) == ("shellingham==1.5.4",)


@pytest.mark.root
@pytest.mark.ros
@pytest.mark.skipif(bool(lab_skip_reason() or ros_skip_reason()), reason=lab_skip_reason() or ros_skip_reason() or "")
def test_a_launch_packages_requirements_go_in_the_hosts_venv_once(tmp_path: Path) -> None:
    if subprocess.run([SYSTEM_PYTHON, "-c", "import shellingham"], capture_output=True).returncode == 0:
        pytest.skip("the system python3 has shellingham already: nothing would show the venv is used")
    if not (WHEELS / ".stamp").exists():
        pytest.skip(f"needs the lab's package mirror ({WHEELS}: bash .ci/lab-wheels.sh)")
    ws = make_workspace(tmp_path / "ws")
    talker = ws / "src" / "fogtest" / "scripts" / "talker.py"
    talker.write_text(LAUNCH_TALKER)
    (tmp_path / "requirements.txt").write_text("shellingham==1.5.4\n")
    lab_env = {"PIP_NO_INDEX": "1", "PIP_FIND_LINKS": str(WHEELS), **PIP_LEAVES_COMPILING}
    with ssh_lab(tmp_path / "lab", 1, env=lab_env) as (hosts, key):
        (host,) = hosts
        plan, access = _lab_plan(tmp_path, host, key, name="launchreqs", nodes=(
            "  - name: talker\n    machine: t3.small\n"
            "    launch: {package: fogtest, file: talker.launch, workspace: ws, requirements: requirements.txt}\n"))
        try:
            first = provision(plan, hosts=access, state_dir=tmp_path, health_timeout=60)
            (outcome,) = first.hosts
            assert outcome.ok, outcome.error
            assert "shellingham==1.5.4" in next(s for s in outcome.steps if s.name == "venv").detail
            env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{plan.hosts[0].master_port}",
                   "ROS_HOSTNAME": "127.0.0.1"}
            echoed = host.ns.run(["rostopic", "echo", "-n", "1", "/chatter"], env=env, timeout=60).stdout
            assert echoed.startswith('data: "shellingham 1.5.4"'), echoed
            _second_up_installs_nothing(plan, access, tmp_path, health_timeout=60)
        finally:
            teardown(plan, hosts=access, state_dir=tmp_path)
