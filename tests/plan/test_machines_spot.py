"""Machines by requirement for spot nodes: ranked by the catalogue's spot estimate, and saying so.

The Spot Instance Advisor's saving differs by type and region, so the cheapest spot type is often
not the cheapest on-demand one; each row below is a case where the catalogue (spot block dated
2025-06-28) makes them differ, or checks that they agree.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.manifest.schema import parse_manifest
from fogiac.targets.aws.catalog import catalog, spot_price
from fogiac.targets.aws.catalog import on_demand as on_demand_price
from fogiac.plan.compile import compile_plan
from fogiac.manifest.machines import NoMachine, Requirement
from fogiac.targets.aws.machines import choose

from .test_machines import manifest, req

# (requirement, region, chosen at spot, its two alternatives at spot, chosen at on-demand)
SPOT_CHEAPEST = [
    (req(gpu="NVIDIA A10G", memory="32"), "us-west-2", "g5.4xlarge", ("g5.2xlarge", "g5.8xlarge"), "g5.2xlarge"),
    (req(vcpus=">=64"), "us-east-1", "c7i-flex.16xlarge", ("r6a.16xlarge", "c5.18xlarge"), "c6a.16xlarge"),
    (req(vcpus="==4", memory="<=8"), "us-west-2", "c6a.xlarge", ("c6i.xlarge", "c5ad.xlarge"), "c6a.xlarge"),
    (req(vcpus=">=4"), "us-east-1", "t3a.xlarge", ("t2.xlarge", "c6a.xlarge"), "t3a.xlarge"),  # same pick, new menu
    (req(vcpus=">=4"), "us-west-2", "c6a.xlarge", ("t3.xlarge", "t3a.xlarge"), "t3a.xlarge"),
    (req(gpu=True), "us-west-2", "g4dn.xlarge", ("g4dn.2xlarge", "p2.xlarge"), "g4dn.xlarge"),
    (req(gpu="T4", vcpus=">=8", memory=">=16"), "us-west-2", "g4dn.2xlarge", ("g4dn.4xlarge", "g4dn.8xlarge"),
     "g4dn.2xlarge"),
]


@pytest.mark.parametrize(("requirement", "region", "chosen", "alternatives", "on_demand"), SPOT_CHEAPEST)
def test_spot_ranks_by_the_spot_estimate(requirement: Requirement, region: str, chosen: str,
                                         alternatives: tuple[str, ...], on_demand: str) -> None:
    choice = choose(requirement, region, spot=True)
    assert (choice.machine, tuple(o.name for o in choice.alternatives)) == (chosen, alternatives)
    assert choice.ranked_by == "spot"
    estimates = [choice.spot_usd_per_hour] + [o.spot_usd_per_hour for o in choice.alternatives]
    assert estimates == [spot_price(n, region) for n in (chosen, *alternatives)]
    assert estimates == sorted(estimates)  # type: ignore[type-var]
    assert choice.usd_per_hour == on_demand_price(chosen, region)  # on-demand still carried: spot's ceiling
    plain = choose(requirement, region)
    assert (plain.machine, plain.ranked_by, plain.spot_usd_per_hour) == (on_demand, "on-demand", None)


def test_spot_ties_go_to_the_smaller_then_the_name() -> None:
    """Equal spot estimates: the smaller machine first, then the name, as at on-demand."""
    assert spot_price("c5.12xlarge", "us-east-1") == spot_price("c6i.12xlarge", "us-east-1") == 0.6732  # a real tie
    offers = catalog().facts.search(region="us-east-1", vcpus="==48", memory="==96", spot=True)
    names = [o.type.name for o in offers]
    assert names.index("c6i.12xlarge") == names.index("c5.12xlarge") + 1


def test_nothing_fits_names_the_closest_with_their_spot_estimates() -> None:
    with pytest.raises(NoMachine, match=r"^no instance type in us-west-2 has gpu MI300; closest: g4ad\.xlarge "
                                        r"\(1x Radeon Pro V520, 4 vCPU, 16 GiB, \$0\.37853/h, spot about \$0\.1438/h\), "):
        choose(req(gpu="MI300"), "us-west-2", spot=True)


@pytest.mark.parametrize(("target", "machine", "ranked_by", "spot_each"), [
    ("aws", "g5.4xlarge", "spot", 0.4872),  # the target buys it as spot: ranked by the estimate
    ("local", "g5.2xlarge", "on-demand", None),  # no spot on this machine: on-demand ranks, as without spot
])
def test_compile_ranks_a_spot_node_by_what_the_target_buys(target: str, machine: str, ranked_by: str,
                                                          spot_each: float | None) -> None:
    text = manifest("{gpu: A10G, memory_gib: 32}", extra="    spot: true\n")
    host = compile_plan(parse_manifest(text), target=target).host("planner")
    assert (host.machine, host.ranked_by, host.spot_usd_per_hour) == (machine, ranked_by, spot_each)


def test_plain_type_with_spot_keeps_working() -> None:
    host = compile_plan(parse_manifest(manifest("g5.xlarge", extra="    spot: true\n"))).host("planner")
    assert (host.machine, host.chosen_for, host.ranked_by, host.alternatives) == ("g5.xlarge", None, None, ())
    assert host.spot and host.spot_usd_per_hour == spot_price("g5.xlarge", "us-west-2")


def test_plan_shows_which_price_ranked_the_menu(tmp_path: Path) -> None:
    path = tmp_path / "req.yaml"
    path.write_text(manifest("{gpu: A10G, memory_gib: 32}", extra="    spot: true\n"))
    shown = CliRunner().invoke(app, ["plan", str(path)])
    assert shown.exit_code == 0, shown.output
    assert (f"planner: g5.4xlarge ($0.4872/h spot est., $1.6240/h on-demand) is the cheapest at spot estimates "
            f"({catalog().spot_as_of}) with gpu A10G, memory_gib >= 32; next: g5.2xlarge ($0.4969/h spot est., "
            "$1.2120/h on-demand), g5.8xlarge ($0.7344/h spot est., $2.4480/h on-demand)") \
        in " ".join(shown.output.split())
    path.write_text(manifest("{gpu: A10G, memory_gib: 32}"))
    shown = CliRunner().invoke(app, ["plan", str(path)])
    assert ("planner: g5.2xlarge ($1.2120/h) is the cheapest at on-demand prices with gpu A10G, memory_gib >= 32; "
            "next: g5.4xlarge ($1.6240/h), g5.8xlarge ($2.4480/h)") in " ".join(shown.output.split())
