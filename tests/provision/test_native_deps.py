"""Native hosts get their workloads' requirements: a venv over the system's python3 and rospy.

A namespace host with its own sshd runs the grasp-planning node on Debian's /usr/bin/python3
(which has rospy but no numpy or torch): provisioning builds a virtual environment with the
workload's pinned requirements, the node registers with the host's master, and a second run
installs nothing. The namespaces have no route to the internet: like a lab with a local package
mirror, their sessions set PIP_INDEX_URL to this machine's package folder (pip finds torch there too).
"""

from __future__ import annotations

import subprocess
from dataclasses import replace
from pathlib import Path

import pytest

from fogiac.errors import ProvisionError
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.provision import provision, teardown, venv
from fogiac.provision.local import LocalHost
from fogiac.targets.hosts.target import HOSTS
from tests.provision.conftest import ros_skip_reason
from tests.provision.sshlab import lab_skip_reason, ssh_lab

SYSTEM_PYTHON = "/usr/bin/python3"


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
    with ssh_lab(tmp_path / "lab", 1, env={"PIP_INDEX_URL": "file:///opt/pypi/simple"}) as (hosts, key):
        (host,) = hosts
        manifest = tmp_path / "fogiac.yaml"
        manifest.write_text(f"""name: venvtest
cloud:
  provider: hosts
  runtime: native
  hosts:
    - {{name: {host.name}, address: {host.address}, user: root, key: {key}}}
nodes:
  - {{name: grasp, machine: t3.small, workload: grasp_planning}}
""")
        plan = compile_plan(load_manifest(manifest))
        access = {n: replace(a, base_dir=str(host.base_dir))
                  for n, a in HOSTS.access(plan, state_dir=tmp_path, python=SYSTEM_PYTHON).items()}
        try:
            first = provision(plan, hosts=access, state_dir=tmp_path, health_timeout=120)
            (outcome,) = first.hosts
            assert outcome.ok, outcome.error
            assert "venv" in outcome.changed and "services" in outcome.changed
            venv_step = next(s for s in outcome.steps if s.name == "venv")
            assert "torch==2.13.0" in venv_step.detail
            script = next(host.base_dir.glob("services/node-grasp.sh")).read_text()
            assert f"exec {host.base_dir}/venv/" in script and "/bin/python -m workloads.grasp_planning node" in script

            again = provision(plan, hosts=access, state_dir=tmp_path, health_timeout=120)
            assert again.no_changes, [(s.name, s.status, s.detail) for s in again.hosts[0].steps]
            assert next(s for s in again.hosts[0].steps if s.name == "venv").status == "ok"
        finally:
            teardown(plan, hosts=access, state_dir=tmp_path)
