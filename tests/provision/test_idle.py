"""Reading a host's autostop watchdog over SSH: a namespace host with sshd and a running watchdog.

The same reader serves every target (:mod:`fogiac.provision.idle`); here it reaches a real sshd,
the aws target's status asks it with the instance's current address and its pinned host key,
and a host that does not answer is one "unreachable" line within the timeout, not a hang.
"""

from __future__ import annotations

import datetime as dt
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from fogiac.lifecycle import sequence
from fogiac.manifest.schema import parse_manifest
from fogiac.lifecycle.report import autostop_line
from fogiac.plan.compile import compile_plan
from fogiac.provision import SshAccess, idle
from fogiac.provision.runner import RECORD
from fogiac.state import stack_dir, write_json_atomic
from fogiac.targets.aws import api
from fogiac.targets.aws.api import InstanceStatus
from fogiac.targets.aws.target import AWS, HOST_KEYS_FILE, watchdogs
from tests.provision.sshlab import LabHost, fingerprint_of, lab_skip_reason, ssh_lab

REPO = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.skipif(lab_skip_reason() is not None, reason=lab_skip_reason() or "")

MANIFEST = """\
name: idler
cloud: {provider: aws, region: us-east-1}
network: {mode: proxy, ssh_from: [203.0.113.7/32]}
nodes:
  - {name: planner, machine: c5.large, image: "ros:noetic-ros-core"}
"""


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[list[LabHost], Path]]:
    with ssh_lab(tmp_path_factory.mktemp("idle-lab"), 1, dead=1) as found:
        yield found


@pytest.fixture
def watchdog(lab: tuple[list[LabHost], Path]) -> Iterator[tuple[LabHost, float]]:
    """The watchdog running on h0 as provisioning starts it, with no edge ever connected: idle from its start."""
    host = lab[0][0]
    run = host.base_dir / "run"
    run.mkdir(parents=True, exist_ok=True)
    (run / "autostop.json").unlink(missing_ok=True)
    started = time.time()
    proc = host.ns.popen([sys.executable, "-m", "fogiac.provision.autostop", "--stats", str(run / "relay.stats.json"),
                          "--run", str(run), "--idle-s", "3600", "--action", "stop", "--power", "services"],
                         cwd=str(REPO))
    try:
        deadline = time.monotonic() + 20
        while not (run / "autostop.json").exists():
            assert proc.poll() is None and time.monotonic() < deadline, "the watchdog wrote no state"
            time.sleep(0.1)
        yield host, started
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def _access(host: LabHost, key: Path) -> SshAccess:
    return SshAccess(address=host.address, user="root", key=key, base_dir=str(host.base_dir),
                     fingerprints=(fingerprint_of(host.host_key_pub),))


def test_the_watchdogs_idle_time_is_read_over_ssh(watchdog: tuple[LabHost, float], lab: tuple[list[LabHost], Path],
                                                  tmp_path: Path) -> None:
    host, started = watchdog
    state = idle.read(_access(host, lab[1]), name="h0", base=str(host.base_dir), known_hosts=tmp_path / "known",
                      stack="idler-dev")
    assert state is not None and state["stopped_at"] is None and state["action"] == "stop"
    assert started - 5 <= state["idle_since"] <= time.time()
    assert state["stops_at"] == pytest.approx(state["idle_since"] + 3600)
    line = autostop_line(state, now=state["idle_since"] + 75)
    assert line == f"idle 1m 15s, autostop at {time.strftime('%H:%M:%S UTC', time.gmtime(state['stops_at']))}"


def test_a_host_without_a_watchdog_reads_as_none(lab: tuple[list[LabHost], Path], tmp_path: Path) -> None:
    host = lab[0][0]
    assert idle.read(_access(host, lab[1]), name="h0", base=str(tmp_path / "nothing-here"),
                     known_hosts=tmp_path / "known", stack="idler-dev") is None


def test_an_unreachable_host_is_one_line_within_the_timeout(lab: tuple[list[LabHost], Path], tmp_path: Path) -> None:
    dead = lab[0][1]
    began = time.monotonic()
    state = idle.read(_access(dead, lab[1]), name="h1", base="/nowhere", known_hosts=tmp_path / "known",
                      stack="idler-dev", timeout=2.0)
    assert state is not None and set(state) == {idle.UNREACHABLE}
    assert state[idle.UNREACHABLE].startswith(f"h1: cannot reach {dead.address}:22 over SSH")
    assert time.monotonic() - began < 15  # the 2 s deadline, not SSH's 60 s for booting hosts
    assert autostop_line(state).startswith("idle time unknown (unreachable: h1: cannot reach")


def _row(host: str, address: str, instance: str = "i-0lab") -> InstanceStatus:
    return InstanceStatus(name=host, instance_id=instance, state="running", machine="c5.large", public_ip=address,
                          private_ip="10.0.1.5", launched=dt.datetime.now(dt.timezone.utc), uptime_s=60.0,
                          cost_usd=0.0, usd_per_hour=0.085)


def test_aws_status_reads_each_running_instance_with_its_pinned_key(
        watchdog: tuple[LabHost, float], lab: tuple[list[LabHost], Path], _state_dir: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    host, _ = watchdog
    plan = compile_plan(parse_manifest(MANIFEST, source="idler.yaml"), target="aws")
    assert plan.autostop is not None  # on by default on aws
    folder = stack_dir(plan.stack)
    # what provisioning recorded (the address then) and the key pinned from the instance's console
    recorded = SshAccess(address="198.51.100.9", user="root", key=lab[1], base_dir=str(host.base_dir))
    write_json_atomic(folder / RECORD, {"hosts": {"planner": {**recorded.describe(), "base": str(host.base_dir),
                                                              "nodes": ["planner"]}}})
    write_json_atomic(folder / HOST_KEYS_FILE, {"i-0lab": [fingerprint_of(host.host_key_pub)]})

    found = watchdogs(plan, [_row("planner", host.address)])  # started again: a new public address
    assert found["planner"] is not None and found["planner"]["idle_since"] is not None
    unpinned = watchdogs(plan, [_row("planner", host.address, instance="i-0other")])
    assert unpinned == {"planner": {idle.UNREACHABLE: "no host key pinned for i-0other"}}

    wrong = {"i-0lab": [fingerprint_of(lab[0][1].host_key_pub)]}  # another host's key: refused, not trusted
    write_json_atomic(folder / HOST_KEYS_FILE, wrong)
    refused = watchdogs(plan, [_row("planner", host.address)])["planner"]
    assert refused is not None and "presented host key" in refused[idle.UNREACHABLE]

    # the whole status: EC2's answer is the one seam faked (LocalStack's addresses are not ours to dial)
    write_json_atomic(folder / HOST_KEYS_FILE, {"i-0lab": [fingerprint_of(host.host_key_pub)]})
    monkeypatch.setattr(api, "status", lambda stack, **kw: [_row("planner", host.address)])
    doc = sequence.status(AWS, plan)
    reading = doc["hosts"][0]["autostop"]
    assert reading["idle_since"] is not None and reading["stopped_at"] is None
    assert doc["cost"]["no_edge_s"] == pytest.approx(time.time() - reading["idle_since"], abs=5)
    lines = [line for line in AWS.render_status(doc) if isinstance(line, str)]
    assert [line for line in lines if line.startswith("planner: idle ") and "autostop at" in line], lines
