"""FogROS2's own examples, as shipped, through ``fogiac import`` and ``plan`` (issue 35 item 26).

The repository BerkeleyAutomation/FogROS2 at commit 71b2709e62ece85896618c5eebf5371148e32c02
(2024-01-24) ships five launch files in ``fogros2_examples/launch/``: ``talker.auto_aws.launch.py``,
``talker.aws.launch.py``, ``talker.gcp.launch.py``, ``talker.kube.launch.py`` and
``talker.local.launch.py``. The files in ``tests/data/fogros2_examples/`` are fogiac's own, written for
this test with the same names and the same shapes (no line of FogROS2's is copied): the regions from a
function of the file returning a dict literal, given to ``find_nearest_region_and_ami`` through a
module attribute; the type from ``find_cheapest_ec2_instance_type(region)`` bound to a name; a
``print`` line; an AMI from a function that computes it on the robot; GCP and Kubernetes machines; a
plain ``LaunchDescription`` with every node on the robot. :data:`EXPECTED` keeps the list: each imports
and plans, or is refused in one line saying why.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from fogiac.errors import ManifestError
from fogiac.manifest.fogros2 import import_launch
from fogiac.plan.compile import compile_plan

EXAMPLES = Path(__file__).parent / "data" / "fogros2_examples"
_OTHER = ("FogROS2's {} machines are not imported: fogiac runs on AWS (AWSCloudInstance, target aws) or on "
          "machines you have (target hosts)")
# file -> ("plans", region, {node: machine}) or ("refused", what the line is at, its text after "file:line: ")
EXPECTED: dict[str, tuple] = {
    "talker.auto_aws.launch.py": ("plans", "us-west-1", {"talker": "t3a.nano"}),  # TZ=UTC: the first listed
    "talker.aws.launch.py": ("plans", "us-west-1", {"talker": "c5.4xlarge"}),
    "talker.gcp.launch.py": ("refused", "GCPCloudInstance", _OTHER.format("GCP")),
    "talker.kube.launch.py": ("refused", "KubeInstance", _OTHER.format("Kubernetes")),
    "talker.local.launch.py": ("refused", None, "nothing here runs in the cloud (no CloudNode, no "
                               "add_docker_container): every node stays on the robot, so fogiac has nothing to deploy"),
}


def _line(path: Path, needle: str | None, nth: int = 1) -> int:
    """The line of ``needle``'s nth appearance in ``path`` (1 for None: the file as a whole)."""
    if needle is None:
        return 1
    return [i + 1 for i, text in enumerate(path.read_text().splitlines()) if needle in text][nth - 1]


def test_the_list_names_every_example() -> None:
    assert sorted(p.name for p in EXAMPLES.glob("*.py")) == sorted(EXPECTED)


@pytest.mark.parametrize("name", EXPECTED)
def test_each_example_plans_or_is_refused_in_one_line(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TZ", "UTC")  # a place no region is nearer: the first listed, as offline
    path = EXAMPLES / name
    expected = EXPECTED[name]
    if expected[0] == "refused":
        with pytest.raises(ManifestError) as info:
            import_launch(path)
        assert info.value.problems == [f"{path}:{_line(path, expected[1])}: {expected[2]}"]
        return
    converted = import_launch(path)
    assert converted.manifest.cloud.region == expected[1]
    assert "#   - fogros2_examples/listener" in converted.text  # the listener stays on the robot
    plan = compile_plan(converted.manifest, target="aws")
    assert {h.name: h.machine for h in plan.hosts} == expected[2]
    assert plan.host("talker").usd_per_hour > 0


def test_the_auto_example_takes_the_listed_region_nearest_this_machine(monkeypatch: pytest.MonkeyPatch) -> None:
    """FogROS2 asks where the robot's address is at launch; offline, fogiac takes this machine's time zone."""
    path = EXAMPLES / "talker.auto_aws.launch.py"
    for zone, region in (("Asia/Tokyo", "ap-northeast-1"), ("America/New_York", "us-east-1"),
                         ("Europe/Paris", "eu-west-1"), ("America/Los_Angeles", "us-west-1")):
        monkeypatch.setenv("TZ", zone)
        converted = import_launch(path)
        assert converted.manifest.cloud.region == region, zone
        assert (f"fogiac uses {region}, the nearest to this machine's time zone ({zone}): set yours if the robot "
                "is elsewhere") in converted.text
    monkeypatch.setenv("TZ", "UTC")
    converted = import_launch(path)
    assert ("#   - cloud.region: FogROS2 picked the region nearest the robot at launch time among us-west-1, "
            "us-east-1, ap-northeast-1, eu-west-1 (find_nearest_region_and_ami); fogiac uses the first, us-west-1: "
            "set yours (this machine's time zone (UTC) does not say where it is)") in converted.text.splitlines()
    machine = converted.manifest.nodes[0].machine  # find_cheapest_ec2_instance_type(region): 2 cores, 1 thread each
    assert not isinstance(machine, str) and (machine.vcpus, machine.gpu) == ("==2", None)


def _variant(tmp_path: Path, old: str, new: str, name: str = "variant.launch.py") -> Path:
    text = (EXAMPLES / "talker.auto_aws.launch.py").read_text()
    assert old in text
    path = tmp_path / name
    path.write_text(text.replace(old, new))
    return path


def test_only_statements_without_effect_are_passed_over(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TZ", "UTC")
    logged = _variant(tmp_path, "    print(region, ami, kind)\n",
                      "    log = logging.getLogger(__name__)\n    log.info('chose %s', region)\n"
                      "    logging.warning(f'{kind}')\n    print(region, ami, kind, sep=', ')\n")
    assert import_launch(logged).manifest.cloud.region == "us-west-1"
    # print or log whose arguments call something might act: one line, as any other unknown statement
    acting = _variant(tmp_path, "    print(region, ami, kind)\n", "    print(open('/tmp/x', 'w').write('x'))\n")
    with pytest.raises(ManifestError) as info:
        import_launch(acting)
    at = _line(acting, "print(")
    assert info.value.problems == [f"{acting}:{at}: fogiac cannot import \"print(open('/tmp/x', 'w').write('x'))\" "
                                   "(not a FogROS2 construct it knows)"]


def test_a_function_is_read_only_if_it_returns_a_literal(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TZ", "UTC")
    computed = _variant(tmp_path, "    return {\n", "    import os\n    return {\n")
    with pytest.raises(ManifestError) as info:
        import_launch(computed)
    assert info.value.problems == [
        f"{computed}:{_line(computed, 'candidate_regions()', 2)}: candidate_regions() is worked out when the launch "
        "file runs; fogiac reads only a function that takes no arguments and returns a literal: write the value here"]
    # the same for a region given by a function of the file: a literal one is read, others refused
    named = _variant(tmp_path, "host = fogros2.AWSCloudInstance(region=region,",
                     "host = fogros2.AWSCloudInstance(region=home(),", "named.launch.py")
    named.write_text(named.read_text() + "\n\ndef home():\n    \"\"\"The lab's region.\"\"\"\n    return 'eu-west-1'\n")
    assert import_launch(named).manifest.cloud.region == "eu-west-1"


def test_machines_in_several_regions_are_refused_in_one_line(tmp_path: Path) -> None:
    text = (EXAMPLES / "talker.aws.launch.py").read_text().replace(
        "    hearing = Node(",
        "    far = fogros2.AWSCloudInstance(region=\"eu-west-1\", ec2_instance_type=\"t3.small\")\n"
        "    ld.add_action(fogros2.CloudNode(package=\"p\", executable=\"e\", machine=far))\n    hearing = Node(")
    path = tmp_path / "two.launch.py"
    path.write_text(text)
    near, far = _line(path, "AWSCloudInstance"), _line(path, "AWSCloudInstance", 2)
    with pytest.raises(ManifestError) as info:
        import_launch(path)
    assert info.value.problems == [
        f"{path}:{far}: machines in several regions ('eu-west-1' at line {far}, 'us-west-1' at line {near}): a fogiac "
        "manifest deploys to one region; put the machines in one, or split the launch file by region and import "
        "each part as a stack of its own"]
