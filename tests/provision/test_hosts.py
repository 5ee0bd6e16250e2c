"""Provisioning real SSH hosts: namespaces with their own sshd, roscore and rospy node.

One deployment (two hosts) is shared by the tests of this module, in order: first run, no-op
re-run, a changed file pushed alone, a killed node restarted, host keys refused, an unreachable
host failing alone, and teardown.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Iterator

import pytest

from fogiac.certs import load_or_create_bundle
from fogiac.manifest.schema import load_manifest
from fogiac.net.relay.tls import relay_name
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Plan
from fogiac.provision import ProvisionReport, SshAccess, provision, teardown
from fogiac.targets.hosts.placement import stack_ports
from fogiac.targets.hosts.target import HOSTS
from tests.provision.conftest import hosts_manifest, make_workspace, ros_skip_reason
from tests.provision.sshlab import LabHost, fingerprint_of, lab_skip_reason, ssh_lab
from tests.support.tls import dial, private_keys_under, public_der

pytestmark = [pytest.mark.root, pytest.mark.ros]

_REASON = lab_skip_reason() or ros_skip_reason()
if _REASON:
    pytest.skip(_REASON, allow_module_level=True)

_QUERY = """
import json, sys, xmlrpc.client
m = xmlrpc.client.ServerProxy(f"http://127.0.0.1:{sys.argv[2]}")
code, _, uri = m.lookupNode("/t", sys.argv[1])
pid = xmlrpc.client.ServerProxy(uri).getPid("/t")[2] if code == 1 else None
print(json.dumps({"code": code, "pid": pid}))
"""


class Deployment:
    def __init__(self, root: Path, hosts: list[LabHost], key: Path) -> None:
        self.root, self.hosts, self.key = root, hosts, key
        self.state = root / "state"
        self.state.mkdir()
        self.workspace = make_workspace(root / "ws", extra_files=20)
        self.certs = root / "certs"
        load_or_create_bundle("labtest-dev", self.certs)

    def plan(self, hosts: list[LabHost]) -> Plan:
        manifest = hosts_manifest(self.root / "fogiac.yaml", hosts=[(h.name, h.address) for h in hosts],
                                  key=self.key, workspace=self.workspace)
        return compile_plan(load_manifest(manifest))

    def access(self, plan: Plan, *, timeout: float = 30.0) -> dict[str, SshAccess]:
        by_name = {h.name: h for h in self.hosts}
        base = HOSTS.access(plan, state_dir=self.state, python=sys.executable, connect_timeout=timeout)
        # ship_code off: the namespaces share this checkout, and other work edits fogiac/ meanwhile
        return {n: replace(a, base_dir=str(by_name[n].base_dir), ship_code=False) for n, a in base.items()}

    def provision(self, hosts: list[LabHost] | None = None, *, timeout: float = 30.0) -> ProvisionReport:
        plan = self.plan(hosts or self.hosts[:2])
        return provision(plan, hosts=self.access(plan, timeout=timeout), state_dir=self.state,
                         certs_dir=self.certs, health_timeout=30)

    def node_pid(self, host: LabHost) -> int | None:
        port = self.plan(self.hosts[:2]).hosts[0].master_port  # the stack's own, not 11311: the lab may run one
        out = host.ns.run(["/usr/bin/python3", "-c", _QUERY, "/fog_talker", str(port)]).stdout
        return json.loads(out)["pid"]


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Deployment]:
    root = tmp_path_factory.mktemp("sshlab")
    with ssh_lab(root, 2, dead=1) as (hosts, key):
        yield Deployment(root, hosts, key)


def _status(report: ProvisionReport) -> dict[str, tuple[str | None, tuple[str, ...]]]:
    return {h.host: (h.error, h.changed) for h in report.hosts}


def test_first_run_starts_a_rospy_node_inside_each_namespace(lab: Deployment) -> None:
    report = lab.provision()
    assert report.ok, [h.error for h in report.hosts]
    for outcome in report.hosts:
        assert {"runtime", "workspace", "services"} <= set(outcome.changed), outcome
    for host in lab.hosts[:2]:
        pid = lab.node_pid(host)
        assert pid in host.ns.pids(), ("the node runs inside the host's own namespace", pid, report)
    known = lab.state / "known_hosts"
    assert known.stat().st_mode & 0o777 == 0o600
    assert len(known.read_text().splitlines()) == 2


def test_rerun_with_nothing_changed_is_a_no_op(lab: Deployment) -> None:
    report = lab.provision()
    assert report.summary() == "no changes"
    assert all(h.changed == () and h.bytes_sent == 0 for h in report.hosts)


def test_one_changed_file_is_pushed_alone_and_restarts_its_node(lab: Deployment) -> None:
    before = lab.node_pid(lab.hosts[0])
    config = lab.workspace / "src" / "fogtest" / "config" / "params_007.yaml"
    config.write_text(config.read_text() + "extra: 1\n")
    report = lab.provision()
    assert report.ok
    for outcome in report.hosts:
        workspace = next(s for s in outcome.steps if s.name == "workspace")
        assert workspace.detail.startswith("pushed 1 file(s), ")
        assert outcome.changed == ("workspace", "env_script", "services")
    pushed = (lab.hosts[0].base_dir / "ws").glob("ws-*/src/fogtest/config/params_007.yaml")
    assert next(pushed).read_text().endswith("extra: 1\n")
    assert not list((lab.hosts[0].base_dir / "ws").glob("ws-*/build")), "build/ is ignored"
    assert not list((lab.hosts[0].base_dir / "ws").glob("ws-*/notes.tmp")), ".fogiacignore is honoured"
    assert lab.node_pid(lab.hosts[0]) != before


def test_a_killed_node_is_restarted_by_the_supervisor(lab: Deployment) -> None:
    host = lab.hosts[1]
    pid = lab.node_pid(host)
    assert pid is not None
    os.kill(pid, signal.SIGKILL)
    deadline = time.monotonic() + 60
    new = None
    while time.monotonic() < deadline:
        try:
            new = lab.node_pid(host)
        except (RuntimeError, ValueError, KeyError):
            new = None
        if new not in (None, pid) and new in host.ns.pids():
            break
        time.sleep(0.5)
    assert new not in (None, pid)
    state = json.loads((host.base_dir / "run" / "node-talker-h1.state").read_text())
    assert state["restarts"] >= 1


def test_a_changed_host_key_is_refused(lab: Deployment) -> None:
    known = lab.state / "known_hosts"
    saved = known.read_text()
    other = lab.hosts[2].host_key_pub.read_text().split()
    lines = [f"{ln.split()[0]} {other[0]} {other[1]}" if ln.startswith(lab.hosts[1].address + " ") else ln
             for ln in saved.splitlines()]
    known.write_text("\n".join(lines) + "\n")
    try:
        report = lab.provision()
    finally:
        known.write_text(saved)
    status = _status(report)
    assert status["h0"] == (None, ())
    error = status["h1"][0] or ""
    assert error.startswith(f"h1 ({lab.hosts[1].address}) presented host key {fingerprint_of(lab.hosts[1].host_key_pub)}")
    assert f"records {fingerprint_of(lab.hosts[2].host_key_pub)}; refusing to connect" in error
    assert report.summary() == "1 of 2 host(s) failed"


def test_pinned_fingerprints_accept_the_right_key_and_refuse_others(lab: Deployment, tmp_path: Path) -> None:
    plan = lab.plan(lab.hosts[:1])
    access = lab.access(plan)["h0"]
    right = replace(access, fingerprints=(fingerprint_of(lab.hosts[0].host_key_pub),))
    wrong = replace(access, fingerprints=("SHA256:" + "A" * 43,))
    from fogiac.errors import HostKeyError

    with pytest.raises(HostKeyError, match=r"^h0 \(10\.232\.\d+\.2\) presented host key SHA256:\S+, which is not "
                                           r"among the 1 pinned fingerprint\(s\) the instance reported"):
        wrong.open(name="h0", known_hosts=tmp_path / "kh", stack="s").connect()
    host = right.open(name="h0", known_hosts=tmp_path / "kh", stack="s")
    assert host.connect() == 1
    host.close()
    assert (tmp_path / "kh").read_text().startswith(lab.hosts[0].address + " ssh-ed25519 ")


def test_an_unreachable_host_fails_with_a_clear_line_while_the_others_succeed(lab: Deployment) -> None:
    report = lab.provision(lab.hosts, timeout=3.0)
    status = _status(report)
    assert status["h0"] == (None, ())
    assert status["h1"] == (None, ())
    dead = lab.hosts[2]
    assert (status["h2"][0] or "").startswith(f"h2: cannot reach {dead.address}:22 over SSH after ")
    assert (status["h2"][0] or "").endswith(" in 3s (Connection refused)")
    assert not report.ok


def test_relay_step_pushes_cloud_certs_private(lab: Deployment) -> None:
    relay_cli = (Path(__file__).resolve().parents[2] / "fogiac" / "cli" / "relay.py").exists()
    status = json.loads((lab.hosts[0].base_dir / "run" / "relay-cloud.state").read_text()) if relay_cli else None
    if relay_cli:  # the relay's CLI exists: its cloud end runs supervised, listening in the namespace
        assert status is not None and status["child"] in lab.hosts[0].ns.pids()
    certs = lab.hosts[0].base_dir / "certs"
    assert sorted(p.name for p in certs.iterdir()) == ["ca.pem", "server.key", "server.pem"]
    assert (certs / "server.key").stat().st_mode & 0o777 == 0o600
    script = (lab.hosts[0].base_dir / "services" / "relay-cloud.sh").read_text()
    master, relay = stack_ports("labtest-dev")
    assert f"-m fogiac relay cloud --listen 0.0.0.0:{relay} --master http://127.0.0.1:{master} --certs {certs}" in script


def test_each_host_has_its_own_relay_key_which_never_left_it(lab: Deployment) -> None:
    """Over real SSH: the key was made on the host, the operator's folders hold none of it, and
    the edge dialing h0's running cloud end as h1 refuses h0's certificate."""
    stack = lab.plan(lab.hosts[:2]).stack
    mine = [public_der((h.base_dir / "certs" / "server.pem").read_bytes()) for h in lab.hosts[:2]]
    assert mine[0] != mine[1]
    operator = {k for folder in (lab.state, lab.certs) for keys in private_keys_under(folder).values() for k in keys}
    assert not set(mine) & operator
    address = (lab.hosts[0].address, lab.plan(lab.hosts[:2]).host("h0").relay_port)  # the stack's own port
    assert dial(address, lab.certs, relay_name(stack, "h0")) is None
    refused = dial(address, lab.certs, relay_name(stack, "h1"))
    assert refused is not None and "Hostname mismatch" in refused


def test_teardown_stops_every_process_and_removes_the_base(lab: Deployment) -> None:
    plan = lab.plan(lab.hosts[:2])
    report = teardown(plan, hosts=lab.access(plan), state_dir=lab.state)
    assert report.ok
    for host in lab.hosts[:2]:
        assert not host.base_dir.exists()
        sshd_only = [p for p in host.ns.pids() if "sshd" not in Path(f"/proc/{p}/cmdline").read_text()]
        assert sshd_only == []


def test_the_console_pin_wins_over_a_key_recorded_for_an_earlier_instance(lab: Deployment, tmp_path: Path) -> None:
    """A public address reused by a fresh instance: the old instance's key is still recorded, the
    console pins the new one. The pin proves the new key; the stale line is replaced."""
    plan = lab.plan(lab.hosts[:1])
    access = replace(lab.access(plan)["h0"], fingerprints=(fingerprint_of(lab.hosts[0].host_key_pub),))
    stale = lab.hosts[2].host_key_pub.read_text().split()
    known = tmp_path / "kh"
    known.write_text(f"{lab.hosts[0].address} {stale[0]} {stale[1]}\n")
    host = access.open(name="h0", known_hosts=known, stack="s")
    assert host.connect() == 1
    host.close()
    real = lab.hosts[0].host_key_pub.read_text().split()
    assert known.read_text() == f"{lab.hosts[0].address} {real[0]} {real[1]}\n"
