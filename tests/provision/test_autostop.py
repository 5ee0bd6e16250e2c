"""Autostop: the idle clock (pure), then a real local sandbox that stops itself once its edge is gone."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.manifest.schema import load_manifest
from fogiac.net.relay.stats import RelayStats, TopicStats, write_stats
from fogiac.lifecycle.edge import stop_edge
from fogiac.lifecycle.report import autostop_line
from fogiac.plan.compile import compile_plan
from fogiac.procs import free_port
from fogiac.provision.autostop import Activity, IdleClock, read_activity
from tests.provision.conftest import make_workspace, ros_skip_reason


def stats(*, connected: bool, msgs: int = 0) -> Activity:
    return Activity(connected=connected, msgs=msgs)


def test_the_watchdog_reads_the_relays_stats_and_the_zenoh_routers(tmp_path: Path) -> None:
    topics = (TopicStats("/chatter", "out", 0.0, 0.0, 7, 70, 0, None, None, "none"),
              TopicStats("/scan", "in", 0.0, 0.0, 5, 50, 0, None, None, "none"))
    relay = tmp_path / "relay-cloud.stats.json"
    write_stats(relay, RelayStats(role="cloud", connected=True, rtt_ms=None, clock_offset_ms=0.0, reconnects=0,
                                  topics=topics))
    assert read_activity(relay) == Activity(connected=True, msgs=12)
    router = tmp_path / "zenoh-router.stats.json"
    router.write_text(json.dumps({"routers": [], "connected": False}))  # as the router writes it (router.serve)
    assert read_activity(router) == Activity(connected=False, msgs=None)
    router.write_text('{"routers": ["ab')  # half a file: no word from it, not "connected"
    assert read_activity(router) is None and read_activity(tmp_path / "missing") is None


def test_connected_edge_or_moving_counters_keep_a_host_in_use() -> None:
    clock = IdleClock(idle_s=60, now=0)
    clock.observe(stats(connected=True, msgs=5), now=10)
    assert (clock.idle_since(10), clock.due(69)) == (None, False)
    clock.observe(stats(connected=False, msgs=5), now=20)  # the edge left; counters still
    assert clock.idle_since(20) == 10
    clock.observe(stats(connected=False, msgs=9), now=30)  # messages crossed in the last poll
    assert clock.idle_since(30) is None and not clock.due(89)
    clock.observe(stats(connected=False, msgs=9), now=90)
    assert clock.due(90) and clock.idle_since(90) == 30


def test_a_host_whose_edge_never_came_is_idle_from_the_start() -> None:
    clock = IdleClock(idle_s=5, now=100)
    clock.observe(None, now=103)
    assert clock.idle_since(103) == 100 and not clock.due(104)
    clock.observe(None, now=105)
    assert clock.due(105)


def test_a_restarted_host_waits_its_grace_for_the_edge_then_idle_s_alone_counts() -> None:
    """CI regression: ``up`` restarted a sandbox with a 3 s autostop and its edge end took longer than 3 s
    to dial in on a loaded machine; the watchdog stopped every service under that ``up``."""
    clock = IdleClock(idle_s=3, now=0, grace_s=60)
    clock.observe(stats(connected=False), now=5)
    assert not clock.due(5) and clock.stops_at() == 60 and clock.idle_since(5) == 0
    clock.observe(stats(connected=True), now=8)  # the edge linked: from now on idle_s alone
    clock.observe(stats(connected=False), now=9)
    assert clock.stops_at() == 11 and not clock.due(10.9) and clock.due(11)
    unlinked = IdleClock(idle_s=3, now=0, grace_s=60)  # an edge that never came: stopped after the grace
    unlinked.observe(None, now=59)
    assert not unlinked.due(59) and unlinked.due(60)


def test_status_line_says_what_happened() -> None:
    assert autostop_line({"idle_since": None, "stops_at": None, "stopped_at": None, "action": "stop"}) == \
        "in use (autostop stop after idle)"
    assert autostop_line({"idle_since": 0, "stops_at": 600, "stopped_at": None, "action": "stop"}, now=250) == \
        "idle 4m 10s, autostop at 00:10:00 UTC"
    assert autostop_line({"idle_since": 0, "stops_at": 600, "stopped_at": 600, "action": "terminate"}) == \
        "terminated by autostop at 00:10:00 UTC (idle since 00:00:00 UTC)"


MANIFEST = """name: idler
cloud:
  provider: local
  autostop: {{idle_minutes: 0.05, action: stop}}
edge: {{ros_master: "http://127.0.0.1:{port}"}}
nodes:
  - name: talker
    machine: t3.small
    launch: {{package: fogtest, file: talker.launch, workspace: ws}}
"""


def _status(runner: CliRunner, manifest: Path) -> dict:
    out = runner.invoke(app, ["status", str(manifest), "--json"])
    assert out.exit_code == 0, out.output
    return json.loads(out.output)


@pytest.mark.ros
@pytest.mark.skipif(ros_skip_reason() is not None, reason=str(ros_skip_reason()))
def test_sandbox_stops_when_its_edge_leaves_and_up_starts_it_again(tmp_path: Path, _state_dir: Path) -> None:
    make_workspace(tmp_path / "ws")
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(MANIFEST.format(port=free_port()))
    plan = compile_plan(load_manifest(manifest))
    assert plan.autostop is not None and plan.autostop.idle_s == 3.0
    runner = CliRunner()
    try:
        up = runner.invoke(app, ["up", str(manifest), "--yes", "--start-edge-master"])
        assert up.exit_code == 0, up.output
        (host,) = _status(runner, manifest)["hosts"]
        assert host["nodes"][0]["running"] is True
        # The watchdog saw the edge linked (idle_since None) before it leaves: from then on idle_s alone counts.
        # Leaving earlier, before its first poll saw the link, tests the start grace (60 s) instead, which
        # took this test past its deadline on a loaded machine.
        deadline = time.monotonic() + 60
        while (host["autostop"] or {"idle_since": 0})["idle_since"] is not None:
            assert time.monotonic() < deadline, f"the watchdog never saw the edge linked: {host}"
            time.sleep(0.2)
            (host,) = _status(runner, manifest)["hosts"]

        stop_edge(plan, keep_master=True)  # the edge disconnects
        deadline = time.monotonic() + 60
        while not (host["autostop"] or {}).get("stopped_at"):
            assert time.monotonic() < deadline, f"the sandbox never stopped: {host}"
            time.sleep(0.5)
            (host,) = _status(runner, manifest)["hosts"]
        assert host["nodes"][0]["running"] is False
        human = runner.invoke(app, ["status", str(manifest)])
        assert "talker: stopped by autostop at" in human.output

        again = runner.invoke(app, ["up", str(manifest), "--yes", "--start-edge-master"])
        assert again.exit_code == 0, again.output
        assert " 0 files, 0 B" in again.output, again.output  # unchanged code is not pushed again
        deadline = time.monotonic() + 30  # the restarted watchdog rewrites its state on its first poll
        (host,) = _status(runner, manifest)["hosts"]
        while host["autostop"]["stopped_at"] is not None:
            assert time.monotonic() < deadline, f"the watchdog did not start again: {host}"
            time.sleep(0.3)
            (host,) = _status(runner, manifest)["hosts"]
        assert host["nodes"][0]["running"] is True
    finally:
        down = runner.invoke(app, ["down", str(manifest), "--yes"])
    assert down.exit_code == 0, down.output
