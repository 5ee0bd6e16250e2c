"""Spot prices in the catalogue, with their date and source, and both prices in plan and cost."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.manifest.schema import parse_manifest
from fogiac.targets.aws.catalog import catalog, spot_price
from fogiac.targets.aws.catalog import on_demand as od_price
from fogiac.plan.compile import compile_plan
from fogiac.plan.cost import cost, hosts, saving_pct
from fogiac.targets.aws.spot import on_demand

SPOT = """\
name: spotty
cloud: {provider: aws, region: us-east-1}
network: {mode: proxy, ssh_from: [203.0.113.7/32]}
nodes:
  - {name: grasp, machine: g4dn.xlarge, image: "ros:noetic-ros-core", spot: true}
  - {name: planner, machine: c5.large, image: "ros:noetic-ros-core"}
"""


def test_every_type_has_a_dated_spot_price_at_most_on_demand_in_every_region() -> None:
    cat = catalog()
    assert re.fullmatch(r"\d{4}-\d{2}-\d{2}", cat.spot_as_of)
    assert "Spot Instance Advisor" in cat.spot_source and "spot-advisor-data.json" in cat.spot_source
    assert "on-demand price x (1 - savings/100)" in cat.spot_method
    for name in cat.facts.types:
        for region in cat.facts.regions_offering(name):
            spot, od = spot_price(name, region), od_price(name, region)
            assert spot is None or 0 < spot <= od, (name, region)


# (type, region, on-demand, the estimate): the catalogue's own figures
ESTIMATES = [
    ("g4dn.xlarge", "us-east-1", 0.526, 0.1894),
    ("c5.24xlarge", "us-east-1", 4.08, 1.1016),
    ("c5.24xlarge", "us-west-2", 4.08, 1.3872),
    ("p3.2xlarge", "us-west-2", 3.06, 0.8874),
]


@pytest.mark.parametrize(("name", "region", "od", "spot"), ESTIMATES)
def test_the_estimate_is_on_demand_less_the_saving(name: str, region: str, od: float, spot: float) -> None:
    assert (od_price(name, region), spot_price(name, region)) == (od, spot)
    assert spot_price(name, "sa-east-1") is None  # a region the catalogue cannot price


def test_a_spot_host_carries_both_prices_and_the_plan_both_totals() -> None:
    plan = compile_plan(parse_manifest(SPOT, source="spot.yaml"), target="aws")
    rows = {h["name"]: h for h in hosts(plan)}
    assert (rows["grasp"]["usd_per_hour"], rows["grasp"]["spot_usd_per_hour"]) == (0.526, 0.1894)
    assert (rows["planner"]["spot"], rows["planner"]["spot_usd_per_hour"]) == (False, None)
    doc = cost(plan)
    assert [(line["item"], line["usd_per_hour"], line["spot_usd_per_hour"]) for line in doc["lines"]] == [
        ("instance grasp (g4dn.xlarge, spot)", 0.526, 0.1894), ("instance planner (c5.large)", 0.085, None)]
    assert (doc["hourly_usd"], doc["spot_hourly_usd"]) == (0.611, 0.2744)
    assert doc["spot_prices"]["as_of"] == catalog().spot_as_of


def test_an_all_on_demand_plan_has_no_spot_total() -> None:
    plan = compile_plan(parse_manifest(SPOT.replace("spot: true", "spot: false"), source="od.yaml"), target="aws")
    assert plan.spot_hourly_usd is None
    assert "spot_hourly_usd" not in cost(plan) and "spot_prices" not in cost(plan)


def test_falling_back_to_on_demand_drops_the_spot_price() -> None:
    plan = on_demand(compile_plan(parse_manifest(SPOT, source="spot.yaml"), target="aws"), ["grasp"])
    assert [(h.name, h.spot, h.spot_usd_per_hour) for h in plan.hosts] == [("grasp", False, None),
                                                                           ("planner", False, None)]
    assert [line.item for line in plan.cost] == ["instance grasp (g4dn.xlarge)", "instance planner (c5.large)"]
    assert plan.spot_hourly_usd is None and plan.hourly_usd == 0.611


def test_plan_and_cost_print_both_prices_and_where_spot_comes_from(tmp_path: Path) -> None:
    path = tmp_path / "spot.yaml"
    path.write_text(SPOT)
    runner = CliRunner()
    shown = runner.invoke(app, ["plan", str(path)], env={"COLUMNS": "250"})
    assert shown.exit_code == 0, shown.output
    assert "0.1894 (64% less)" in shown.output  # the spot host's row: on-demand 0.5260 beside it
    assert re.search(r"total\s.*0\.6110\s.*0\.2744", shown.output)
    assert (f"with spot: about $0.2744 per hour ($200.31 per month (730 h)), {saving_pct(0.611, 0.2744)}% less; "
            f"spot estimates from {catalog().spot_source.split(' (')[0]} ({catalog().spot_as_of})") in shown.output
    doc = json.loads(runner.invoke(app, ["plan", str(path), "--json"]).stdout)
    assert (doc["cost"]["hourly_usd"], doc["cost"]["spot_hourly_usd"]) == (0.611, 0.2744)
    priced = runner.invoke(app, ["cost", str(path)], env={"COLUMNS": "250"})
    assert priced.exit_code == 0, priced.output
    assert re.search(r"instance grasp \(g4dn\.xlarge, spot\)\s.*0\.5260\s.*0\.1894", priced.output)
    assert "with spot: $0.2744 per hour, 55% less than on-demand" in priced.output
    assert f"spot prices: {catalog().spot_source} ({catalog().spot_as_of})" in priced.output.replace("\n", " ")
