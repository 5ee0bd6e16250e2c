"""Machines by requirement: the cheapest catalogue type that fits, ties, and 'nothing fits' in one line."""

from __future__ import annotations

import re

import pytest

from fogiac.errors import ManifestError
from fogiac.manifest.schema import parse_manifest
from fogiac.plan.compile import compile_plan
from fogiac.manifest.machines import Bound, NoMachine, Requirement, parse_bound
from fogiac.targets.aws.machines import choose


def req(gpu: bool | str | None = None, vcpus: str | None = None, memory: str | None = None) -> Requirement:
    return Requirement(gpu=gpu, vcpus=parse_bound(vcpus) if vcpus else None,
                       memory_gib=parse_bound(memory) if memory else None)


# (requirement, region, chosen, the two alternatives) -- prices from the shipped catalogue (every
# current and previous family; a requirement without arch is x86_64, and a CPU one pays for no accelerator)
CHEAPEST = [
    (req(gpu="T4", vcpus=">=8", memory=">=16"), "us-west-2", "g4dn.2xlarge", ("g4dn.4xlarge", "g4dn.8xlarge")),
    (req(gpu="t4"), "us-east-1", "g4dn.xlarge", ("g4dn.2xlarge", "g4dn.4xlarge")),
    (req(gpu=True), "us-west-2", "g4dn.xlarge", ("g4dn.2xlarge", "g6.xlarge")),
    (req(gpu="NVIDIA A10G", memory="32"), "us-west-2", "g5.2xlarge", ("g5.4xlarge", "g5.8xlarge")),
    (req(gpu="V100"), "us-west-2", "p3.2xlarge", ("p3.8xlarge", "p3.16xlarge")),
    (req(vcpus="2", memory=">=1"), "us-west-2", "t3a.micro", ("t3.micro", "t3a.small")),
    (req(vcpus=">=64"), "us-west-2", "c6a.16xlarge", ("c5a.16xlarge", "c7i-flex.16xlarge")),
    (req(vcpus="==4", memory="<=8"), "us-west-2", "c6a.xlarge", ("c5a.xlarge", "c7i-flex.xlarge")),
    (req(vcpus=">2", memory="<16"), "us-west-2", "c6a.xlarge", ("c5a.xlarge", "c7i-flex.xlarge")),
    (Requirement(arch="arm64", vcpus=parse_bound(">=8")), "us-west-2", "a1.2xlarge", ("t4g.2xlarge", "c6g.2xlarge")),
    # EC2 reports a 24 GB card (A10G, L4) as 22.4 GiB
    (Requirement(gpu_memory_gib=parse_bound(">=22")), "us-east-1", "g6.xlarge", ("g6.2xlarge", "g5.xlarge")),
    (req(gpu="L4", vcpus=">=4"), "us-east-1", "g6.xlarge", ("g6.2xlarge", "g6.4xlarge")),
    (req(gpu="A10G", vcpus=">=16"), "us-west-2", "g5.4xlarge", ("g5.8xlarge", "g5.16xlarge")),
]


@pytest.mark.parametrize(("requirement", "region", "chosen", "alternatives"), CHEAPEST)
def test_cheapest_match_and_next_two(requirement: Requirement, region: str, chosen: str,
                                     alternatives: tuple[str, ...]) -> None:
    choice = choose(requirement, region)
    assert choice.machine == chosen
    assert tuple(o.name for o in choice.alternatives) == alternatives
    prices = [choice.usd_per_hour] + [o.usd_per_hour for o in choice.alternatives]
    assert prices == sorted(prices)


# Equal prices: the smaller machine first, then the name.
TIES = [
    (req(vcpus=">=48", memory="<=96"), "c6a.12xlarge", ("c5a.12xlarge", "c7i-flex.12xlarge")),
    (req(vcpus="==48", memory="==96"), "c6a.12xlarge", ("c5a.12xlarge", "c7i-flex.12xlarge")),
    (req(vcpus="==96", memory="192"), "c6a.24xlarge", ("c5a.24xlarge", "c5.24xlarge")),
]


@pytest.mark.parametrize(("requirement", "chosen", "alternatives"), TIES)
def test_ties_go_to_the_smaller_then_the_name(requirement: Requirement, chosen: str,
                                              alternatives: tuple[str, ...]) -> None:
    choice = choose(requirement, "us-west-2")
    assert (choice.machine, tuple(o.name for o in choice.alternatives)) == (chosen, alternatives)


NOTHING = [
    (req(gpu="MI300"), r"^no instance type in us-west-2 has gpu MI300; closest: g4ad\.xlarge \(1x Radeon Pro V520, "
                       r"4 vCPU, 16 GiB, \$0\.37853/h\), g4dn\.xlarge .*$"),
    (req(gpu="T4", vcpus=">=200"), r"^no instance type in us-west-2 has gpu T4, vcpus >= 200; "
                                   r"closest: g4dn\.metal .*, g4dn\.16xlarge .*, g4dn\.12xlarge .*$"),
    (req(vcpus=">=8", memory="<2"), r"^no instance type in us-west-2 has vcpus >= 8, memory_gib < 2; closest: "),
]


@pytest.mark.parametrize(("requirement", "message"), NOTHING)
def test_nothing_matches_names_the_closest_in_one_line(requirement: Requirement, message: str) -> None:
    with pytest.raises(NoMachine, match=message) as info:
        choose(requirement, "us-west-2")
    assert "\n" not in str(info.value)
    assert str(info.value).count("$") == 3


@pytest.mark.parametrize(("text", "bound"), [
    ("8", Bound(">=", 8)), (">=8", Bound(">=", 8)), ("< 64", Bound("<", 64)), ("==16", Bound("==", 16)),
    (16, Bound(">=", 16)), (7.5, Bound(">=", 7.5)), (" <= 0.5 ", Bound("<=", 0.5)),
])
def test_bounds(text: str | int | float, bound: Bound) -> None:
    assert parse_bound(text) == bound


@pytest.mark.parametrize("text", ["about 8", "=>8", "", ">=", True, "8 GiB"])
def test_bad_bounds_say_the_forms(text: str | bool) -> None:
    with pytest.raises(ValueError, match=r"is not a bound; write a number or e\.g\. '>=8', '<=64', '==16'$"):
        parse_bound(text)


def manifest(machine: str, *, extra: str = "") -> str:
    return f"name: req\nnodes:\n  - name: planner\n    machine: {machine}\n    image: ros:noetic\n{extra}"


def test_compile_resolves_and_the_plan_shows_the_menu() -> None:
    plan = compile_plan(parse_manifest(manifest('{gpu: T4, vcpus: ">=8", memory_gib: ">=16"}')))
    host = plan.host("planner")
    assert (host.machine, host.vcpus, host.gpus, host.usd_per_hour) == ("g4dn.2xlarge", 8, 1, 0.752)
    assert host.chosen_for == "gpu T4, vcpus >= 8, memory_gib >= 16"
    assert [(o.name, o.usd_per_hour) for o in host.alternatives] == [("g4dn.4xlarge", 1.204), ("g4dn.8xlarge", 2.176)]
    assert plan.node("planner").gpu  # a GPU requirement means the node runs with the GPU
    assert plan.cost[0].item == "instance planner (g4dn.2xlarge)"


def test_node_gpu_flag_asks_for_any_gpu() -> None:
    plan = compile_plan(parse_manifest(manifest("{vcpus: 8}", extra="    gpu: true\n")))
    assert plan.host("planner").machine == "g4dn.2xlarge"


def test_plain_type_name_keeps_working_and_has_no_menu() -> None:
    for spelling in ("g5.xlarge", "{type: g5.xlarge}"):
        host = compile_plan(parse_manifest(manifest(spelling))).host("planner")
        assert (host.machine, host.chosen_for, host.alternatives) == ("g5.xlarge", None, ())


@pytest.mark.parametrize(("machine", "message"), [
    ("{gpu: MI300}", "nodes[0].machine: no instance type in us-west-2 has gpu MI300; closest: "),
    ("{type: c5.large, vcpus: 4}", "nodes[0].machine: give either type or requirements (vcpus), not both"),
    ("{}", "nodes[0].machine: needs a type or at least one of gpu, vcpus, memory_gib, arch, gpu_memory_gib"),
    ("{vcpu: 8}", "nodes[0].machine.vcpu: unknown key; did you mean 'vcpus'?"),
    ('{vcpus: "about 8"}', "nodes[0].machine.vcpus: 'about 8' is not a bound"),
    ("{type: c5.lrge}", "nodes[0].machine.type: 'c5.lrge' is not a known instance type; did you mean 'c5.large'?"),
])
def test_manifest_errors_are_one_line_at_the_machine(machine: str, message: str) -> None:
    with pytest.raises(ManifestError) as info:
        parse_manifest(manifest(machine), source="m.yaml")
    # one problem line; the cross-field rules that need the broken machine say they were skipped
    lines = [line for line in str(info.value).splitlines() if "checks across fields skipped" not in line]
    assert len(lines) == 1
    assert re.match(r"^m\.yaml:4: " + re.escape(message), lines[0]), lines[0]
