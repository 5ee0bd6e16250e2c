"""A ROS 2 host on the native runtime: its Zenoh router runs in the venv provisioning builds.

A namespace host with its own sshd and Debian's /usr/bin/python3 (which has no eclipse-zenoh):
provisioning pushes fogiac's code, builds the virtual environment with fogiac's requirements and
the Zenoh middleware's (from the lab's package mirror, as a lab without PyPI would), makes the
router's key on the host and starts the router from that environment; the edge router on this
machine dials the namespace's address over mutual TLS and the host's router sees it linked.
"""

from __future__ import annotations

import subprocess
from dataclasses import replace
from pathlib import Path

import pytest

from fogiac.manifest.schema import load_manifest
from fogiac.net import middleware
from fogiac.lifecycle.edge import edge_dir, provision_and_connect, stop_edge
from fogiac.plan.compile import compile_plan
from fogiac.procs import free_port, poll
from fogiac.provision import teardown
from fogiac.state import read_json
from fogiac.targets.hosts.target import HOSTS
from tests.provision.conftest import ros_skip_reason
from tests.provision.sshlab import lab_skip_reason, ssh_lab
from tests.support.ros2 import standin_ros2

SYSTEM_PYTHON = "/usr/bin/python3"
WHEELS = Path("/var/cache/fogiac-ci/lab-wheels")
MIRROR = {"PIP_INDEX_URL": "file:///opt/pypi/simple", "PIP_FIND_LINKS": str(WHEELS)}
SYSTEM_PATH = "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"


def _why_not() -> str | None:
    reason = lab_skip_reason() or ros_skip_reason()
    if reason:
        return reason
    if not list(WHEELS.glob("eclipse_zenoh-1.10.2-*.whl")):
        return f"needs the lab's package mirror with eclipse-zenoh ({WHEELS}: bash .ci/lab-wheels.sh)"
    if subprocess.run([SYSTEM_PYTHON, "-c", "import zenoh"], capture_output=True).returncode == 0:
        return "the system python3 has eclipse-zenoh already: nothing would show the venv is used"
    return None


pytestmark = [pytest.mark.root, pytest.mark.zenoh, pytest.mark.skipif(_why_not() is not None, reason=_why_not() or "")]


def test_the_router_runs_from_the_venv_and_the_edge_links_to_it(tmp_path: Path, _state_dir: Path) -> None:
    pytest.importorskip("zenoh", reason="needs eclipse-zenoh here for the edge router")
    # ROS 2 in the host's login environment (a stand-in: tests.support.ros2), as its admins would set it up.
    login = dict(MIRROR, PATH=f"{standin_ros2(tmp_path / 'ros2')}:{SYSTEM_PATH}")
    with ssh_lab(tmp_path / "lab", 1, env=login) as (hosts, key):
        (host,) = hosts
        manifest = tmp_path / "fogiac.yaml"
        manifest.write_text(f"""name: zlab
ros: {{distro: jazzy}}
cloud:
  provider: hosts
  runtime: native
  hosts:
    - {{name: lab1, address: {host.address}, user: root, key: {key}}}
edge: {{zenoh_router: "tcp/127.0.0.1:{free_port()}"}}
nodes:
  - {{name: idle, machine: t3.small, command: [sleep, "3600"], topics: {{out: [/detections]}}}}
""")
        plan = compile_plan(load_manifest(manifest))
        access = {n: replace(a, base_dir=str(host.base_dir))
                  for n, a in HOSTS.access(plan, state_dir=tmp_path, python=SYSTEM_PYTHON).items()}
        connect = {n: f"{a.address}:{plan.host(n).relay_port}" for n, a in access.items()}
        try:
            done = provision_and_connect(plan, access=access, connect=connect, master=plan.edge_master)
            (outcome,) = done.report.hosts
            venv_step = next(s for s in outcome.steps if s.name == "venv")
            assert "eclipse-zenoh==1.10.2" in venv_step.detail, venv_step.detail
            (venv_python,) = host.base_dir.glob("venv/*/bin/python")
            script = (host.base_dir / "services" / "zenoh-router.sh").read_text()
            assert f"exec {venv_python} -m fogiac.net.zenoh.router" in script.replace("'", "")
            assert (host.base_dir / "certs" / "zenoh" / "server.key").stat().st_mode & 0o777 == 0o600

            carrier = middleware.deployment(plan.middleware)
            linked = poll(lambda: [link for link in carrier.edge_links(plan, folder=edge_dir(plan), connect=done.relays)
                                   if link["connected"]] or None, timeout=30)
            assert linked, f"the edge router never linked to {connect}"
            stats = host.base_dir / "run" / "zenoh-router.stats.json"
            assert poll(lambda: (read_json(stats) or {}).get("connected") or None, timeout=10)
        finally:
            stop_edge(plan)
            teardown(plan, hosts=access, state_dir=_state_dir / "zlab-dev")
