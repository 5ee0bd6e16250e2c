"""Replicas on the ``hosts`` target (issue 24): a node's two replicas on two namespace lab hosts, each
with its own master and relay; one host "dies" (every fogiac process there killed, its folder gone) and
provisioning the same plan again brings it back while the other replica runs on untouched.

Real sshd in network namespaces (tests/provision/sshlab.py), real roscore and the real talker node.
Run under ``flock /tmp/fogiac-netns.lock``.
"""

from __future__ import annotations

import json
import shutil
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from fogiac.certs import load_or_create_bundle
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.provision import provision, teardown
from fogiac.targets.hosts.target import HOSTS
from tests.provision.conftest import make_workspace, ros_skip_reason
from tests.provision.sshlab import kill_host, lab_skip_reason, ssh_lab
from tests.support.procs import alive, started_pids


def _states(run: Path) -> dict[str, tuple[int, int]]:
    """{service: (child pid, restarts)} as the supervisor records them."""
    return {p.stem: (json.loads(p.read_text())["child"], json.loads(p.read_text())["restarts"])
            for p in sorted(run.glob("*.state"))}


@pytest.mark.skipif(bool(lab_skip_reason() or ros_skip_reason()), reason=lab_skip_reason() or ros_skip_reason() or "")
def test_two_replicas_on_two_lab_hosts_and_a_dead_one_comes_back(tmp_path: Path) -> None:
    with ssh_lab(tmp_path / "lab", 2) as (hosts, key):
        state, certs = tmp_path / "state", tmp_path / "certs"
        state.mkdir()
        load_or_create_bundle("reps-dev", certs)
        ws = make_workspace(tmp_path / "ws")
        lines = ["name: reps", "cloud:", "  provider: hosts", "  hosts:"]
        for host in hosts:
            lines += [f"    - {{name: {host.name}, address: {host.address}, user: root, key: {key}}}"]
        lines += ["nodes:", "  - name: talker", "    machine: t3.small",
                  f"    launch: {{package: fogtest, file: talker.launch, workspace: {ws}}}",
                  "    replicas: 2", f"    replica_hosts: [{hosts[1].name}, {hosts[0].name}]",
                  "    topics: {in: [/request], out: [/chatter]}",
                  "    reply_match: data", "    message_types: {/chatter: std_msgs/String}"]
        (tmp_path / "fogiac.yaml").write_text("\n".join(lines) + "\n")
        plan = compile_plan(load_manifest(tmp_path / "fogiac.yaml"))
        assert {r.host: (r.replica.group, r.replica.index) for r in plan.routes if r.replica} == {
            hosts[1].name: ("talker", 0), hosts[0].name: ("talker", 1)}
        by_name = {h.name: h for h in hosts}
        access = {n: replace(a, base_dir=str(by_name[n].base_dir / "reps"), ship_code=False)
                  for n, a in HOSTS.access(plan, state_dir=state, python=sys.executable).items()}
        runs = {n: Path(a.base_dir) / "run" for n, a in access.items()}
        try:
            report = provision(plan, hosts=access, state_dir=state, certs_dir=certs, health_timeout=30)
            assert report.ok, [h.error for h in report.hosts]
            healthy, doomed = hosts[0].name, hosts[1].name
            before = _states(runs[healthy])
            assert "node-talker" in before and alive(before["node-talker"][0])

            assert [pid for pid in started_pids(Path(access[doomed].base_dir)) if alive(pid)]
            kill_host(by_name[doomed])  # the replica's machine dies: every process there (roscore's rosmaster
            shutil.rmtree(access[doomed].base_dir)  # too, which outlived its killed parents before), and its disk

            again = provision(plan, hosts=access, state_dir=state, certs_dir=certs, health_timeout=30)
            assert again.ok, [h.error for h in again.hosts]
            back = _states(runs[doomed])
            assert alive(back["node-talker"][0])
            assert _states(runs[healthy]) == before, "nothing of the healthy replica restarted"
        finally:
            teardown(plan, hosts=access, state_dir=state)
