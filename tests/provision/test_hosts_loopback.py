"""On the ``hosts`` target only the relay faces the lab network (issue 26 item 12): the host's ROS master,
its rospy nodes and the relay's ROS side listen on loopback, so nobody on the lab network registers a
publisher or dials a node to inject into a topic the relay carries to the robot.

A real namespace lab host with its own sshd, provisioned over SSH as ``up`` does; sockets read with
``ss`` inside its network namespace, and dialled from the lab network outside it.
"""

from __future__ import annotations

import socket
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from fogiac.certs import load_or_create_bundle
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.provision import provision, teardown
from fogiac.targets.hosts.target import HOSTS
from tests.provision.conftest import hosts_manifest, make_workspace, ros_skip_reason
from tests.provision.sshlab import lab_skip_reason, ssh_lab

pytestmark = [pytest.mark.root, pytest.mark.ros]

_REASON = lab_skip_reason() or ros_skip_reason()
if _REASON:
    pytest.skip(_REASON, allow_module_level=True)

# roscpp's XML-RPC server binds every interface whatever ROS_IP says (rosout is roscpp): not fogiac's to bind
_ROSCPP = ('(("rosout",',)


def _refused(address: str, port: int) -> bool:
    try:
        socket.create_connection((address, port), timeout=3).close()
    except OSError:
        return True
    return False


def test_only_the_relay_listens_beyond_loopback_on_a_lab_host(tmp_path: Path) -> None:
    with ssh_lab(tmp_path, 1) as (hosts, key):
        host = hosts[0]
        state, certs = tmp_path / "state", tmp_path / "certs"
        state.mkdir()
        load_or_create_bundle("labtest-dev", certs)
        manifest = hosts_manifest(tmp_path / "fogiac.yaml", hosts=[(host.name, host.address)], key=key,
                                  workspace=make_workspace(tmp_path / "ws"))
        plan = compile_plan(load_manifest(manifest))
        access = {n: replace(a, base_dir=str(host.base_dir), ship_code=False)
                  for n, a in HOSTS.access(plan, state_dir=state, python=sys.executable).items()}
        try:
            report = provision(plan, hosts=access, state_dir=state, certs_dir=certs, health_timeout=30)
            assert report.ok, [h.error for h in report.hosts]
            spec = plan.host(host.name)
            lines = host.ns.run(["ss", "-Hltnp"]).stdout.splitlines()
            open_ = {line.split()[3]: line for line in lines if not line.split()[3].startswith("127.0.0.1:")}
            ours = {a: line for a, line in open_.items() if "sshd" not in line and not any(p in line for p in _ROSCPP)}
            assert [a.rsplit(":", 1)[1] for a in ours] == [str(spec.relay_port)], ours  # the relay's TLS port
            assert any(f"127.0.0.1:{spec.master_port}" in line for line in lines), "the master is not running"
            assert _refused(host.address, spec.master_port), "the host's ROS master answers the lab network"
            assert not _refused(host.address, spec.relay_port)
        finally:
            teardown(plan, hosts=access, state_dir=state)
