"""Issue 34: an aws fleet's plan counts one Client VPN connection per robot, not one per fleet.

AWS bills Client VPN by the connection-hour, one per connected client, and every robot's edge joins the stack's
VPC through its own connection; the plan counted one whatever the number of robots. Compiled offline from the
shipped catalogue's prices (the plan's own cost lines; no cloud asked), and through the spot fallback's re-pricing,
which rebuilds the same lines from the plan.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from fogiac.manifest.schema import parse_manifest
from fogiac.plan.compile import compile_plan
from fogiac.targets.aws import spot
from fogiac.targets.aws.catalog import catalog

FLEET = """name: arms
cloud: {provider: aws, region: us-west-2}
network: {mode: vpn, vpc_cidr: 10.10.0.0/16, client_cidr: 10.200.0.0/22}
robots:
  - {name: arm1, ros_master: "http://127.0.0.1:11312"}
  - {name: arm2, ros_master: "http://127.0.0.1:11313"}
  - {name: arm3, ros_master: "http://127.0.0.1:11314"}
nodes:
  - name: planner
    machine: c5.large
    spot: true
    command: [sleep, "3600"]
    topics: {in: [/plan/request], out: [/plan/path]}
"""
ONE = FLEET.split("robots:")[0] + 'edge: {ros_master: "http://127.0.0.1:11312"}\nnodes:' + FLEET.split("nodes:")[1]


def _vpn(plan: object) -> list[tuple[str, float, float | None]]:
    return [(c.item, c.quantity, c.usd_per_hour) for c in plan.cost if "Client VPN" in c.item]  # type: ignore[attr-defined]


def test_each_robot_is_billed_its_own_client_vpn_connection() -> None:
    cat = catalog()
    fleet = compile_plan(parse_manifest(FLEET, base=Path.cwd()))
    assert _vpn(fleet) == [("Client VPN subnet association", 1, cat.vpn_association_usd_per_hour),
                           ("Client VPN connections (3 robots, one each)", 3, cat.vpn_connection_usd_per_hour)]
    one = compile_plan(parse_manifest(ONE, base=Path.cwd()))
    assert _vpn(one) == [("Client VPN subnet association", 1, cat.vpn_association_usd_per_hour),
                         ("Client VPN connection (the edge)", 1, cat.vpn_connection_usd_per_hour)]
    # the fleet costs two more connection-hours an hour than the same stack with one robot
    assert fleet.hourly_usd - one.hourly_usd == pytest.approx(2 * cat.vpn_connection_usd_per_hour)
    # the spot fallback re-prices the plan from its own lines: the connections stay one per robot
    priced = spot.on_demand(fleet, {"planner"})
    assert priced is not fleet and _vpn(priced) == _vpn(fleet)
