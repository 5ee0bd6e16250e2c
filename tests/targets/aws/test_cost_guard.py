"""The aws target's cost guard: instances and the Client VPN association, priced; autostop's stops date the edge."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import pytest

from fogiac.targets.aws.api import InstanceStatus
from fogiac.targets.aws.target import cost_guard
from tests.plan.test_guard import HOUR, NOW, _plan


def _row(state: str, *, stopped_by: str = "", stopped_at: float | None = None, spot: bool = False) -> InstanceStatus:
    launched = dt.datetime.fromtimestamp(NOW - HOUR, dt.timezone.utc)
    return InstanceStatus(
        name="planner", instance_id="i-1", state=state, machine="g4dn.xlarge", public_ip=None, private_ip="10.0.1.5",
        launched=launched, uptime_s=HOUR if state == "running" else 0.0, cost_usd=0.0,
        usd_per_hour=(0.1894 if spot else 0.526) if state == "running" else 0.0,
        stopped_at=dt.datetime.fromtimestamp(stopped_at, dt.timezone.utc) if stopped_at else None,
        stopped_by=stopped_by, spot=spot, spot_estimate=spot)


def test_aws_host_stopped_by_autostop_means_no_edge_since_before_it_stopped(tmp_path: Path) -> None:
    plan = _plan(tmp_path)
    assert plan.autostop is not None and plan.autostop.idle_s == 1800  # the aws default
    outputs = {"network_since": NOW - 3 * HOUR, "network": {"vpn_endpoint_id": "cvpn-endpoint-1"}}
    doc = cost_guard(plan, [_row("stopped", stopped_by="the instance", stopped_at=NOW - HOUR)], outputs, now=NOW)
    assert doc["no_edge_s"] == 1.5 * HOUR
    assert doc["usd_per_hour"] == 0.1 and doc["cost_usd"] == 0.3
    assert doc["warning"].startswith("no edge for 1h 30m, longer than autostop's 30m 00s, and this stack still costs")

    by_hand = cost_guard(plan, [_row("stopped", stopped_by="a user", stopped_at=NOW - HOUR)], outputs, now=NOW)
    assert by_hand["no_edge_s"] is None and by_hand["warning"] == ""  # a user's stop says nothing about the edge
    running = cost_guard(plan, [_row("running")], outputs, now=NOW)
    assert running["usd_per_hour"] == 0.626 and running["cost_usd"] == pytest.approx(0.526 + 0.3)


def test_a_spot_instance_is_billed_at_its_estimate_and_labelled(tmp_path: Path) -> None:
    plan = _plan(tmp_path)
    outputs = {"network_since": NOW - 3 * HOUR, "network": {"vpn_endpoint_id": "cvpn-endpoint-1"}}
    doc = cost_guard(plan, [_row("running", spot=True)], outputs, now=NOW)
    assert doc["lines"][0]["item"] == "instance planner (g4dn.xlarge, spot, running)"
    assert (doc["lines"][0]["spot_estimate"], doc["usd_per_hour"], doc["spot_estimate_as_of"]) == (True, 0.2894,
                                                                                                   "2025-06-28")
    on_demand = cost_guard(plan, [_row("running")], outputs, now=NOW)  # e.g. a spot host that fell back
    assert on_demand["lines"][0]["item"] == "instance planner (g4dn.xlarge, running)"
    assert (on_demand["lines"][0]["spot_estimate"], on_demand["spot_estimate_as_of"]) == (False, None)
