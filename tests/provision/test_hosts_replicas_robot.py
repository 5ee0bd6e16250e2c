"""Replicas on the ``hosts`` target seen from the robot (issue 24): a node with ``replicas: 2`` and
``replica_hosts: [h0, h1]`` provisioned on two namespace lab hosts the way ``fogiac up`` does
(``provision_and_connect``: each host's master, relay cloud end and node under its supervisor; the edge's
replica group on this machine), and a robot on the edge master sending requests stamped in their
``std_msgs/Header``; the node answers each with the same stamp.

- One replica host dies mid-run (every process of its namespace but sshd SIGKILLed) or its link is cut
  (its veth down: no reset, the edge has to notice the silence): every request is answered exactly once.
- One replica sits behind a slow link (``tbf`` at 1 Mbit/s on its veth, 16 KB replies): the healthy one
  wins nearly every request, and the slow one's copies are dropped as late.

Asserts on counts and on which replica won, never on wall-clock time. Real sshd in network namespaces
(tests/provision/sshlab.py), real roscores, the real relay, rospy nodes. Run under
``flock /tmp/fogiac-netns.lock``.
"""

from __future__ import annotations

import contextlib
import json
import sys
from collections import Counter
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import pytest

from fogiac.lifecycle.edge import edge_dir, provision_and_connect, stop_edge
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Plan
from fogiac.procs import free_port
from fogiac.provision import teardown
from fogiac.state import StackState
from fogiac.targets.hosts.target import HOSTS
from tests.net.relay.relay_support import Master, Proc, Procs, wait_for
from tests.provision.conftest import ros_skip_reason
from tests.provision.sshlab import LabHost, kill_host, lab_skip_reason, ssh_lab

NODES = Path(__file__).parents[1] / "net" / "relay" / "replica_nodes.py"
REQ, REP = "/echo/request", "/echo/reply"

pytestmark = [pytest.mark.root, pytest.mark.ros,
              pytest.mark.skipif(bool(lab_skip_reason() or ros_skip_reason()),
                                 reason=lab_skip_reason() or ros_skip_reason() or "")]


@contextlib.contextmanager
def replicated(tmp_path: Path, hosts: list[LabHost], key: Path, *,
               pad: int = 0) -> Iterator[tuple[Plan, Master, Procs]]:
    """The echo node's two replicas up on ``hosts``, the robot's master and the edge's replica group here."""
    procs = Procs(tmp_path / "roshome")
    edge = procs.roscore(free_port())
    lines = ["name: reps", "cloud:", "  provider: hosts", "  hosts:"]
    lines += [f"    - {{name: {h.name}, address: {h.address}, user: root, key: {key}}}" for h in hosts]
    lines += [f'edge: {{ros_master: "{edge.uri.rstrip("/")}"}}', "nodes:", "  - name: echo", "    machine: t3.small",
              f"    command: [{sys.executable}, {NODES}, echo, {REQ}, {REP}, --name, ip, --pad, '{pad}']",
              "    replicas: 2", f"    replica_hosts: [{', '.join(h.name for h in hosts)}]",
              f"    topics: {{in: [{REQ}], out: [{REP}]}}"]
    (tmp_path / "fogiac.yaml").write_text("\n".join(lines) + "\n")
    plan = compile_plan(load_manifest(tmp_path / "fogiac.yaml"))
    by_name = {h.name: h for h in hosts}
    access = {n: replace(a, base_dir=str(by_name[n].base_dir / "reps"), ship_code=False)
              for n, a in HOSTS.access(plan, state_dir=tmp_path, python=sys.executable).items()}
    connect = {n: f"{a.address}:{plan.host(n).relay_port}" for n, a in access.items()}
    try:
        provision_and_connect(plan, access=access, connect=connect, master=plan.edge_master)
        wait_for(lambda: all(r.get("connected") for r in group_stats(plan).get("replicas", [{}])), 60,
                 "both replicas linked to the edge")
        yield plan, edge, procs
    finally:
        stop_edge(plan)
        with contextlib.suppress(Exception):  # a host whose link was cut is back by now; teardown is best effort
            teardown(plan, hosts=access, state_dir=StackState(plan.stack).ensure())
        procs.close()  # each process group signalled, then SIGKILLed (stop_group): no rosmaster outlives it




def group_stats(plan: Plan) -> dict:
    """What the edge's replica group last wrote: per replica won, late, health."""
    try:
        return json.loads((edge_dir(plan) / "relay-replicas-echo.stats.json").read_text())
    except (OSError, ValueError):
        return {}


def robot(procs: Procs, edge: Master, count: int, rate: float) -> Proc:
    proc = procs.spawn([sys.executable, str(NODES), "robot", REQ, REP, "--count", str(count), "--rate", str(rate),
                        "--wait", "5"], edge.env)
    return proc


def replies(proc: Proc) -> list[dict]:
    return [json.loads(line) for line in proc.lines if line.startswith("{")]


def veth(host: LabHost) -> str:
    """The host's side of its link (the namespace's one interface besides lo)."""
    out = host.ns.ip("-o", "link").stdout
    return next(line.split(":")[1].strip().split("@")[0] for line in out.splitlines() if ": lo:" not in line)


@pytest.mark.parametrize("how", ["killed", "cut"])
def test_every_request_answered_once_while_a_replica_host_dies(tmp_path: Path, _state_dir: Path, how: str) -> None:
    count = 80
    with ssh_lab(tmp_path / "lab", 2) as (hosts, key), replicated(tmp_path, hosts, key) as (plan, edge, procs):
        healthy, doomed = hosts
        asking = robot(procs, edge, count, 10.0)
        wait_for(lambda: len(replies(asking)) >= count // 4, 90, "a quarter of the replies")
        before = Counter(r["from"] for r in replies(asking))
        if how == "killed":
            kill_host(doomed)
        else:
            doomed.ns.ip("link", "set", "dev", veth(doomed), "down")
        try:
            wait_for(lambda: "done" in asking.lines, 120, "the robot's run")
        finally:
            if how == "cut":
                doomed.ns.ip("link", "set", "dev", veth(doomed), "up")
        got = replies(asking)
        assert sorted(r["i"] for r in got) == list(range(count)), Counter(r["i"] for r in got)  # once each
        winners = Counter(r["from"] for r in got)
        assert set(winners) <= {healthy.address, doomed.address}
        assert sum(before.values()) >= count // 4 and winners[healthy.address] >= count - sum(before.values()), \
            (before, winners)  # after the host went, only the healthy replica answered
        wait_for(lambda: group_stats(plan).get("delivered", 0) >= count, 15, "the group's figures written")
        stats = group_stats(plan)
        assert stats["delivered"] == count and sum(r["won"] for r in stats["replicas"]) == count
        by_host = {r["host"]: r for r in stats["replicas"]}
        assert by_host[healthy.name]["health"] == "ok"
        assert by_host[doomed.name]["health"] in ("down", "silent"), by_host[doomed.name]  # named as gone


def test_a_replica_behind_a_slow_link_leaves_the_healthy_one_winning(tmp_path: Path, _state_dir: Path) -> None:
    count = 50
    with ssh_lab(tmp_path / "lab", 2) as (hosts, key), \
            replicated(tmp_path, hosts, key, pad=16000) as (plan, edge, procs):
        healthy, slow = hosts
        # 1 Mbit/s out of the slow host: each 16 KB reply waits about 100 ms behind the 4 KB burst
        slow.ns.run(["tc", "qdisc", "add", "dev", veth(slow), "root", "tbf", "rate", "1mbit", "burst", "32kbit",
                     "latency", "400ms"])
        asking = robot(procs, edge, count, 5.0)
        wait_for(lambda: "done" in asking.lines, 120, "the robot's run")
        got = replies(asking)
        assert sorted(r["i"] for r in got) == list(range(count))  # every request answered, none twice
        winners = Counter(r["from"] for r in got)
        assert winners[healthy.address] >= count * 9 // 10, winners  # nearly all
        wait_for(lambda: group_stats(plan).get("delivered", 0) >= count, 15, "the group's figures written")
        by_host = {r["host"]: r for r in group_stats(plan)["replicas"]}
        assert by_host[slow.name]["late"] >= count * 8 // 10, by_host  # it answered too, behind the other
        assert by_host[slow.name]["health"] == "ok"  # slow, not gone
