"""The cost guard: sums per hour and so far, and the warning when a stack outlives its edge."""

from __future__ import annotations

import json
import os
from pathlib import Path

from fogiac.manifest.schema import load_manifest
from fogiac.lifecycle.edge import edge_dir, edge_idle_since
from fogiac.targets.aws.catalog import spot_price
from fogiac.plan.compile import compile_plan
from fogiac.plan.guard import Billed, duration, guard, render, up_summary
from fogiac.plan.model import Plan

NOW = 1_800_000_000.0
HOUR = 3600.0


def _plan(tmp_path: Path, *, autostop: str = "", mode: str = "vpn", target: str = "aws", spot: bool = False) -> Plan:
    path = tmp_path / "g.yaml"
    path.write_text(f"name: guarded\ncloud:\n  provider: {target}\n  region: us-west-2\n{autostop}"
                    f"network:\n  mode: {mode}\nnodes:\n  - name: planner\n    machine: g4dn.xlarge\n"
                    "    gpu: true\n    image: ros:noetic-ros-core\n" + ("    spot: true\n" if spot else ""))
    return compile_plan(load_manifest(path))


def test_sums_per_hour_and_so_far() -> None:
    doc = guard([Billed("instance a", 0.5, NOW - 2 * HOUR), Billed("vpn", 0.1, NOW - 10 * HOUR),
                 Billed("instance b (stopped)", 0.0, None, running=False)],
                now=NOW, autostop_s=1800, edge_idle_since=None)
    assert (doc["usd_per_hour"], doc["cost_usd"], doc["warning"], doc["no_edge_s"]) == (0.6, 2.0, "", None)
    assert [line["cost_usd"] for line in doc["lines"]] == [1.0, 1.0, None]
    assert render(doc)[0] == ("cost: $0.6000/h now, $2.00 so far (on-demand catalogue prices; "
                              "stopped hosts' disks not counted)")


def test_warns_when_no_edge_for_longer_than_autostop_and_money_still_flows() -> None:
    billed = [Billed("instance a (c5.large, stopped)", 0.0, None, running=False),
              Billed("Client VPN subnet association", 0.1, NOW - 5 * HOUR)]
    doc = guard(billed, now=NOW, autostop_s=1800, edge_idle_since=NOW - 2 * HOUR)
    assert doc["warning"] == ("no edge for 2h 00m, longer than autostop's 30m 00s, and this stack still costs "
                              "$0.10/h (Client VPN subnet association): `fogiac down` removes it")
    assert render(doc)[-1] == f"warning: {doc['warning']}"
    assert guard(billed, now=NOW, autostop_s=1800, edge_idle_since=NOW - 600)["warning"] == ""  # not yet
    assert guard(billed, now=NOW, autostop_s=None, edge_idle_since=NOW - 9 * HOUR)["warning"] == ""  # autostop off


def test_warns_when_free_hosts_still_run_past_the_autostop_time() -> None:
    doc = guard([Billed("host planner", 0.0, None)], now=NOW, autostop_s=60, edge_idle_since=NOW - 125)
    assert doc["warning"] == ("no edge for 2m 05s, longer than autostop's 1m 00s, yet host planner still run: "
                              "the autostop watchdog did not stop them (see its log on the host)")
    stopped = guard([Billed("host planner", 0.0, None, running=False)], now=NOW, autostop_s=60,
                    edge_idle_since=NOW - 125)
    assert stopped["warning"] == ""


def test_edge_idle_since_reads_this_machines_edge_relay_stats(tmp_path: Path) -> None:
    plan = _plan(tmp_path, mode="proxy")
    stats = edge_dir(plan) / f"relay-edge-{plan.routes[0].host}.stats.json"
    assert edge_idle_since(plan, now=NOW) is None  # never ran here: unknown
    stats.parent.mkdir(parents=True, exist_ok=True)
    stats.write_text(json.dumps({"connected": True}))
    os.utime(stats, (NOW - 5, NOW - 5))
    assert edge_idle_since(plan, now=NOW) is None  # connected now
    os.utime(stats, (NOW - HOUR, NOW - HOUR))
    assert edge_idle_since(plan, now=NOW) == NOW - HOUR  # the relay stopped writing an hour ago


def test_up_summary_says_what_autostop_does_about_the_cost(tmp_path: Path) -> None:
    assert up_summary(_plan(tmp_path)) == (
        "cost: $0.6760/h while up; autostop stops the hosts after 30m 00s without an edge; "
        "the Client VPN association is billed until `fogiac down`")
    off = _plan(tmp_path, autostop="  autostop: off\n", mode="proxy")
    assert up_summary(off) == "cost: $0.5260/h while up; autostop is off: it costs this until `fogiac down`"
    assert duration(59) == "0m 59s" and duration(7260) == "2h 01m"


def test_spot_lines_are_priced_at_the_estimate_and_say_so() -> None:
    billed = [Billed("instance a (g4dn.xlarge, spot, running)", 0.1894, NOW - 2 * HOUR, spot_estimate=True),
              Billed("Client VPN subnet association", 0.1, NOW - 2 * HOUR)]
    doc = guard(billed, now=NOW, autostop_s=1800, edge_idle_since=NOW - HOUR)
    assert (doc["usd_per_hour"], doc["cost_usd"], doc["spot_estimate_as_of"]) == (0.2894, 0.5788, "2025-06-28")
    assert render(doc)[:3] == [
        "cost: $0.2894/h now, $0.58 so far (on-demand catalogue prices, spot instances at the catalogue's spot "
        "estimate of 2025-06-28; stopped hosts' disks not counted)",
        "  $0.1894/h     $0.38 so far  instance a (g4dn.xlarge, spot, running) (spot estimate)",
        "  $0.1000/h     $0.20 so far  Client VPN subnet association"]
    assert doc["warning"].startswith("no edge for 1h 00m, longer than autostop's 30m 00s, and this stack still "
                                     "costs about $0.29/h (instance a")
    plain = guard(billed[1:], now=NOW, autostop_s=None, edge_idle_since=None)
    assert plain["spot_estimate_as_of"] is None and "spot" not in render(plain)[0]


def test_up_summary_prices_spot_hosts_at_the_estimate_with_on_demand_as_the_ceiling(tmp_path: Path) -> None:
    spot = spot_price("g4dn.xlarge", "us-west-2")
    assert spot is not None
    assert up_summary(_plan(tmp_path, spot=True)) == (
        f"cost: about ${spot + 0.15:.4f}/h while up (spot hosts at the catalogue's spot estimate of 2025-06-28; "
        "$0.6760/h at on-demand prices, the most spot costs); autostop stops the hosts after 30m 00s without an "
        "edge; the Client VPN association is billed until `fogiac down`")
