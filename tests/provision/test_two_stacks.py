"""Two stacks on one lab machine: each has its own ROS master port, relay port, folder and units.

A lab GPU server is shared: two researchers (or one with a dev and a test stack) deploy to the
same machine. The namespace host runs both stacks at once; both are healthy, each node sits on its
own stack's master, and ``down`` of one leaves the other's processes untouched.
"""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from fogiac.certs import load_or_create_bundle
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import RELAY_PORT, ROS_MASTER_PORT, Plan
from fogiac.procs import poll
from fogiac.provision import SshAccess, provision, teardown
from fogiac.provision import services as svc
from fogiac.provision.managers import Systemd
from fogiac.targets.hosts.placement import stack_ports
from fogiac.targets.hosts.target import HOSTS
from tests.provision.conftest import hosts_manifest, make_workspace, ros_skip_reason
from tests.provision.sshlab import LabHost, lab_skip_reason, ssh_lab

_LOOKUP = """
import json, sys, xmlrpc.client
code, _, uri = xmlrpc.client.ServerProxy(f"http://127.0.0.1:{sys.argv[1]}").lookupNode("/t", "/fog_talker")
print(json.dumps(xmlrpc.client.ServerProxy(uri).getPid("/t")[2] if code == 1 else None))
"""


def _plan(root: Path, name: str, *, provider: str = "hosts") -> Plan:
    ws = root / "ws"
    if not ws.exists():
        make_workspace(ws)
        (root / "key").write_text("not read: nothing connects\n")
    manifest = hosts_manifest(root / f"{name}.yaml", hosts=[("h0", "10.232.0.2")], key=root / "key", workspace=ws,
                              name=name)
    return compile_plan(load_manifest(manifest), target=provider)


def test_stacks_on_shared_hosts_get_ports_of_their_own_and_aws_hosts_keep_ros_defaults(tmp_path: Path) -> None:
    alpha, beta = _plan(tmp_path, "alpha"), _plan(tmp_path, "beta")
    (a,), (b,) = alpha.hosts, beta.hosts
    assert (a.master_port, a.relay_port) == stack_ports("alpha-dev") == stack_ports("alpha-dev")
    assert {a.master_port, a.relay_port}.isdisjoint({b.master_port, b.relay_port, ROS_MASTER_PORT, RELAY_PORT})
    assert alpha.routes[0].port == a.relay_port and 20000 <= a.master_port < 30000
    (ports,) = HOSTS.ports(alpha, state_dir=tmp_path).values()  # what the target hands provisioning beside the access
    assert (ports.master_port, ports.relay_port) == (a.master_port, a.relay_port)
    (own,) = _plan(tmp_path, "alpha", provider="aws").hosts  # an instance of its own: ROS's usual ports
    assert (own.master_port, own.relay_port) == (ROS_MASTER_PORT, None)


def test_systemd_units_carry_the_stack_and_order_after_their_own_master(tmp_path: Path) -> None:
    plan = _plan(tmp_path, "alpha")
    spec = plan.hosts[0]
    layout = svc.Layout("/home/lab/.fogiac/alpha-dev/h0", plan.stack)
    where = svc.Where(layout=layout, runtime=svc.NATIVE, master_port=spec.master_port, relay_port=spec.relay_port or 0,
                      ros_address="10.0.0.5", python="python3", code_root="/opt/fogiac")
    (node,) = svc.node_services(plan, spec, where)
    assert "After=network-online.target fogiac-alpha-dev-ros-master.service\n" in node.unit
    assert Systemd.unit(layout, node.name) == "fogiac-alpha-dev-node-talker-h0.service"
    assert Systemd().logs_command(layout, "node-talker-h0", lines=5) == (
        "journalctl -u fogiac-alpha-dev-node-talker-h0.service -n 5 --no-pager")


@pytest.mark.root
@pytest.mark.ros
@pytest.mark.skipif(bool(lab_skip_reason() or ros_skip_reason()), reason=lab_skip_reason() or ros_skip_reason() or "")
def test_two_stacks_share_one_host_and_down_of_one_leaves_the_other_running(tmp_path: Path) -> None:
    with ssh_lab(tmp_path / "lab", 1) as (hosts, key):
        (host,) = hosts
        stacks = {name: _lab_stack(tmp_path / name, host, key, name) for name in ("alpha", "beta")}
        try:
            for name, (plan, access, state, certs) in stacks.items():
                report = provision(plan, hosts=access, state_dir=state, certs_dir=certs, health_timeout=30)
                assert report.ok, (name, [h.error for h in report.hosts])
            pids = {name: _node_pid(host, plan.hosts[0].master_port) for name, (plan, *_) in stacks.items()}
            assert None not in pids.values() and pids["alpha"] != pids["beta"], pids
            assert set(pids.values()) <= set(host.ns.pids()), "each node runs inside the namespace host"
            wanted = [p for plan, *_ in stacks.values() for p in (f":{plan.hosts[0].master_port} ",
                                                                   f"0.0.0.0:{plan.hosts[0].relay_port} ")]
            # a relay counts as started once its process runs; it listens a moment later
            listening = poll(lambda: (lambda out: out if all(w in out for w in wanted) else None)(
                host.ns.run(["ss", "-ltnH"]).stdout), timeout=20)
            assert listening is not None, (wanted, host.ns.run(["ss", "-ltnH"]).stdout)

            beta_run = host.base_dir / "beta" / "run"
            before = _states(beta_run)
            plan, access, state, _ = stacks["alpha"]
            down = teardown(plan, hosts=access, state_dir=state)
            assert down.ok and "node-talker-h0" in down.hosts[0].stopped
            assert not (host.base_dir / "alpha").exists()
            beta = stacks["beta"][0].hosts[0]
            assert _node_pid(host, beta.master_port) == pids["beta"], "beta's node was not touched"
            assert pids["beta"] in host.ns.pids() and pids["alpha"] not in host.ns.pids()
            assert _states(beta_run) == before, "nothing of beta's restarted"
        finally:
            for plan, access, state, _ in stacks.values():
                teardown(plan, hosts=access, state_dir=state)


def _lab_stack(root: Path, host: LabHost, key: Path, name: str) -> tuple[Plan, dict[str, SshAccess], Path, Path]:
    root.mkdir()
    state, certs = root / "state", root / "certs"
    state.mkdir()
    load_or_create_bundle(f"{name}-dev", certs)
    manifest = hosts_manifest(root / "fogiac.yaml", hosts=[(host.name, host.address)], key=key,
                              workspace=make_workspace(root / "ws"), name=name)
    plan = compile_plan(load_manifest(manifest))
    # Both stacks' folders under the host's own (the namespaces share this filesystem); on a real
    # machine each defaults to ~/.fogiac/<stack>/<host>. ship_code off: the namespace sees this checkout.
    access = {n: replace(a, base_dir=str(host.base_dir / name), ship_code=False)
              for n, a in HOSTS.access(plan, state_dir=state, python=sys.executable).items()}
    return plan, access, state, certs


def _states(run: Path) -> dict[str, tuple[int, int]]:
    """{service: (child pid, restarts)} as the supervisor records them."""
    out = {}
    for name in ("ros-master", "relay-cloud", "node-talker-h0"):
        state = json.loads((run / f"{name}.state").read_text())
        out[name] = (state["child"], state["restarts"])
    return out


def _node_pid(host: LabHost, master_port: int) -> int | None:
    return json.loads(host.ns.run(["/usr/bin/python3", "-c", _LOOKUP, str(master_port)]).stdout)
