"""Issue 25's table, planned offline over the whole catalogue: each machine priced in its region with a
dated source (or, where the catalogue has no price, a one-line 'cost unknown' warning), Graviton with
an arm64 image, requirements resolved to the cheapest fit, and real-but-uncatalogued names accepted."""

from __future__ import annotations

import warnings

import pytest

from fogiac.errors import ManifestError
from fogiac.manifest.machines import CostUnknown
from fogiac.manifest.schema import parse_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Plan
from fogiac.targets.aws.manifest import CLOUD


def plan(machine: str, region: str, *, gpu: bool = False) -> Plan:
    text = (f"name: table\ncloud: {{region: {region}}}\nnodes:\n  - name: n\n    machine: {machine}\n"
            f"    image: 'ros:humble'\n" + ("    gpu: true\n" if gpu else ""))
    return compile_plan(parse_manifest(text, source="table.yaml"), target="aws")


# (type, region, on-demand $/h, the note naming its source and date, gpu)
TABLE = [
    ("g6.xlarge", "eu-central-1", 0.93051, True),
    ("c7i.8xlarge", "ap-northeast-1", 1.86354, False),
    ("t2.micro", "us-west-1", 0.01382, False),
    ("g5.2xlarge", "us-east-2", 1.212, True),
    ("c7g.4xlarge", "eu-west-1", 0.64745, False),
]


@pytest.mark.parametrize(("machine", "region", "usd", "gpu"), TABLE)
def test_the_issues_table_plans_offline_priced_in_its_region(machine: str, region: str, usd: float,
                                                             gpu: bool) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error", CostUnknown)  # every one of these is priced
        host = plan(machine, region, gpu=gpu).host("n")
    assert (host.machine, host.usd_per_hour) == (machine, usd)
    assert CLOUD.price_note(machine, region) == (
        f"{machine} in {region}: ${usd:g}/h on-demand (estimate), estimate: us-east-1 price x the region's median "
        "price ratio (2026-07-20)")


def test_us_east_1_prices_come_from_the_price_list_itself() -> None:
    assert CLOUD.price_note("g6.xlarge", "us-east-1") == (
        "g6.xlarge in us-east-1: $0.8048/h on-demand, AWS Price List API via aws/karpenter-provider-aws "
        "zz_generated.pricing_aws.go (2026-07-20)")


@pytest.mark.parametrize(("machine", "region"), [
    ("m5.large", "sa-east-1"), ("m5.large", "ap-south-2"), ("m7i.large", "ap-southeast-5"), ("m5.large", "ca-west-1"),
    ("m5.large", "eu-central-2"), ("m5.large", "il-central-1")])
def test_the_six_unpriced_regions_plan_with_a_one_line_cost_unknown_warning(machine: str, region: str) -> None:
    with pytest.warns(CostUnknown) as caught:
        host = plan(machine, region).host("n")
    assert host.usd_per_hour is None  # unknown, never $0 (issue 35: costs that are unknown say so)
    assert [str(w.message) for w in caught][:1] == [
        f"{machine} in {region}: cost unknown (the catalogue has no price there); `fogiac catalog update` "
        "refreshes the catalogue"]


def test_an_arm64_machine_gets_the_arm64_image() -> None:
    assert plan("c7g.4xlarge", "eu-west-1").host("n").image.description == "Ubuntu 24.04 LTS (Canonical), arm64"
    assert plan("g5g.xlarge", "us-east-1", gpu=True).host("n").image.description == (
        "AWS Deep Learning ARM64 Base, NVIDIA driver, Ubuntu 22.04")
    assert plan("c7i.8xlarge", "ap-northeast-1").host("n").image.description == "Ubuntu 24.04 LTS (Canonical)"


@pytest.mark.parametrize(("need", "region", "chosen"), [
    ('{gpu: L4, vcpus: ">=4"}', "us-east-1", "g6.xlarge"),
    ('{gpu: A10G, vcpus: ">=16"}', "us-west-2", "g5.4xlarge"),
])
def test_requirements_resolve_to_the_cheapest_fit_in_the_region(need: str, region: str, chosen: str) -> None:
    host = plan(need, region).host("n")
    assert host.machine == chosen and host.alternatives


def test_real_names_outside_the_catalogue_are_accepted_with_a_warning_and_typos_refused() -> None:
    with pytest.warns(CostUnknown, match=r"^g3\.4xlarge in us-east-1: cost unknown"):
        host = plan("g3.4xlarge", "us-east-1").host("n")  # botocore's EC2 model lists it; the catalogue does not
    assert (host.machine, host.usd_per_hour) == ("g3.4xlarge", None)  # price unknown
    with pytest.warns(CostUnknown, match=r"^'mx-central-1' is a real AWS region the catalogue does not cover"):
        plan("t3.micro", "mx-central-1")
    with pytest.raises(ManifestError, match=r"'g6.xlrge' is not a known instance type; did you mean 'g6.xlarge'\?"):
        plan("g6.xlrge", "eu-central-1")
    with pytest.raises(ManifestError, match=r"'eu-wset-1' is not a supported region; did you mean 'eu-west-1'\?"):
        plan("t3.micro", "eu-wset-1")


def test_a_type_not_offered_in_the_region_names_the_regions_that_offer_it() -> None:
    with pytest.raises(ManifestError, match=r"nodes\[0\]\.machine: 'p5\.48xlarge' is not offered in af-south-1; "
                                            r"regions that offer it: ap-northeast-1, "):
        plan("p5.48xlarge", "af-south-1")


def test_a_requirement_may_name_the_architecture_and_the_gpu_memory() -> None:
    """``{arch: arm64, vcpus: ">=8"}`` picks a Graviton machine, with the arm64 image; ``gpu_memory_gib``
    bounds all the machine's GPUs together."""
    graviton = plan('{arch: arm64, vcpus: ">=8"}', "eu-west-1").host("n")
    assert CLOUD.machine(graviton.machine).arch == "arm64" and graviton.vcpus >= 8
    assert graviton.image.description.endswith("arm64")
    big = plan('{gpu: true, gpu_memory_gib: ">=40"}', "us-east-1").host("n")
    spec = CLOUD.machine(big.machine)
    assert spec.gpus >= 1 and spec.gpu_memory_gib >= 40
    with pytest.raises(ManifestError, match=r"nodes\[0\]\.machine\.arch: 'sparc' is not one of 'x86_64', 'arm64'"):
        plan("{arch: sparc}", "us-east-1")
