"""``fogiac catalog``: search the EC2 catalogue cheapest first, and ``catalog update`` from AWS's APIs
(LocalStack for EC2, botocore's Stubber for the Price List) writing a catalogue the planner reads."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.manifest.schema import parse_manifest
from fogiac.plan.compile import compile_plan

from .test_refresh import _price_item, _pricing


def _rows(output: str) -> list[list[str]]:
    return [[cell.strip() for cell in line.split("│")[1:-1]] for line in output.splitlines() if line.startswith("│")]


def test_search_filters_and_ranks_cheapest_first() -> None:
    shown = CliRunner().invoke(app, ["catalog", "--gpu", "L4", "--region", "us-east-1", "--limit", "3"],
                               env={"COLUMNS": "200"})
    assert shown.exit_code == 0, shown.output
    rows = _rows(shown.output)
    assert [r[0] for r in rows] == ["g6.xlarge", "g6.2xlarge", "g6.4xlarge"]
    assert rows[0][4:] == ["1x L4", "0.8048", "0.4104", "2026-07-20"]
    graviton = _rows(CliRunner().invoke(app, ["catalog", "--arch", "arm64", "--region", "eu-west-1", "--vcpus", ">=16"],
                                        env={"COLUMNS": "200"}).output)
    assert graviton and {r[3] for r in graviton} == {"arm64"}
    prices = [float(r[5]) for r in graviton]
    assert prices == sorted(prices)


def test_update_writes_the_accounts_catalogue_that_plan_then_prices_from(
        aws_env: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from fogiac.targets.aws import api

    monkeypatch.setenv("FOGIAC_STATE_DIR", str(tmp_path / "state"))
    pricing, stubber = _pricing([_price_item("g6.xlarge", "eu-central-1", "0.9999000000")])
    real = api.client
    monkeypatch.setattr(api, "client", lambda service, *, region: pricing if service == "pricing"
                        else real(service, region=region))
    done = CliRunner().invoke(app, ["catalog", "update", "--region", "eu-central-1"])
    assert done.exit_code == 0, done.output
    written = tmp_path / "state" / "catalogue" / "aws.json.gz"
    assert done.stdout.startswith(f"{written}: ") and "in 1 regions, 1 on-demand prices" in done.stdout
    stubber.assert_no_pending_responses()
    text = ("name: mine\ncloud: {region: eu-central-1}\nnodes:\n"
            "  - {name: gpu, machine: g6.xlarge, image: 'ros:noetic'}\n")
    plan: Any = compile_plan(parse_manifest(text, source="mine.yaml"), target="aws")
    assert plan.host("gpu").usd_per_hour == 0.9999  # the account's price, not the shipped 2026-07-20 estimate


def test_a_region_without_prices_lists_its_types_as_unknown_and_says_how_to_fill_it() -> None:
    """Issue 35, costs that are unknown say so: sa-east-1 has types but no price source; it showed "0 types"."""
    shown = CliRunner().invoke(app, ["catalog", "--region", "sa-east-1", "--vcpus", ">=2", "--limit", "2"],
                               env={"COLUMNS": "200"})
    assert shown.exit_code == 0, shown.output
    assert "EC2 in sa-east-1: " in shown.output and " types, prices unknown" in shown.output
    rows = _rows(shown.output)
    assert len(rows) == 2 and all(r[5] == "unknown" and r[6] == "-" for r in rows), rows
    assert shown.output.rstrip().endswith("The catalogue has no prices for sa-east-1: `fogiac catalog update "
                                          "--region sa-east-1` reads them with your credentials.")


def test_update_of_one_region_fills_its_unknown_prices_and_keeps_the_others(
        aws_env: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 35, costs that are unknown say so: `fogiac catalog update --region sa-east-1` fills that region's
    prices; it wrote a catalogue of sa-east-1 alone, so every other region's machines lost theirs."""
    from fogiac.targets.aws import api
    from fogiac.targets.aws.catalogue import load

    monkeypatch.setenv("FOGIAC_STATE_DIR", str(tmp_path / "state"))
    pricing, stubber = _pricing([_price_item("t3.small", "sa-east-1", "0.0336000000")])
    real = api.client
    monkeypatch.setattr(api, "client", lambda service, *, region: pricing if service == "pricing"
                        else real(service, region=region))
    done = CliRunner().invoke(app, ["catalog", "update", "--region", "sa-east-1", "--no-spot"])
    assert done.exit_code == 0, done.output
    assert "kept " in done.stdout and "warning" not in done.output
    stubber.assert_no_pending_responses()

    def price(region: str) -> Any:
        text = f"name: mine\ncloud: {{region: {region}}}\nnodes:\n  - {{name: a, machine: t3.small, image: 'ros:noetic'}}\n"
        return compile_plan(parse_manifest(text, source="mine.yaml"), target="aws").host("a").usd_per_hour

    assert price("sa-east-1") == 0.0336  # was unknown
    shipped = load().price("t3.small", "us-west-2")
    assert shipped is not None and price("us-west-2") == shipped.usd_per_hour  # kept, not dropped


def test_update_says_when_the_price_list_has_nothing_for_a_region(
        aws_env: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from fogiac.targets.aws import api

    monkeypatch.setenv("FOGIAC_STATE_DIR", str(tmp_path / "state"))
    pricing, _ = _pricing([])
    real = api.client
    monkeypatch.setattr(api, "client", lambda service, *, region: pricing if service == "pricing"
                        else real(service, region=region))
    done = CliRunner().invoke(app, ["catalog", "update", "--region", "sa-east-1", "--no-spot"])
    assert done.exit_code == 0, done.output
    assert ("warning: the Price List answered no on-demand price for sa-east-1: costs there stay unknown"
            in done.output)
