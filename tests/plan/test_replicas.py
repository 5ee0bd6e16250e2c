"""A node's replicas (issue 24, placement): the manifest's fields, the hosts each target gives them, the
Replica on each of their routes, zones on aws, prices and what the plan says."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import pytest

from fogiac.errors import ManifestError, PlanError
from fogiac.manifest.replicas import MatchUnchecked
from fogiac.manifest.schema import load_manifest, parse_manifest
from fogiac.msgtypes import has_header
from fogiac.net.relay.deploy import replicas_argv
from fogiac.plan import cost, diagram
from fogiac.plan.compile import compile_plan
from fogiac.plan.document import document
from fogiac.plan.model import Replica
from fogiac.targets.aws.catalog import on_demand, spot_price
from fogiac.targets.aws.manifest import CLOUD as AWS
from fogiac.targets.aws.offline import declare
from fogiac.plan.review import _host, _node
from tests.conftest import EXAMPLES

PLANNER = """\
  - name: planner
    machine: c5.large
    image: ros:noetic-ros-core
    replicas: 2
    topics: {in: [/plan/request], out: [/plan/path]}
    message_types: {/plan/path: geometry_msgs/PoseArray}
"""


def manifest(cloud: str = "{provider: local}", node: str = PLANNER, others: str = "", base: Path | None = None):
    return parse_manifest(f"name: rep\ncloud: {cloud}\nnodes:\n{node}{others}", source="fogiac.yaml", base=base)


def problems(text: str) -> list[str]:
    with pytest.raises(ManifestError) as err:
        parse_manifest(text, source="fogiac.yaml")
    return err.value.problems


# ------------------------------------------------------------------ the manifest


def test_defaults_run_a_node_once() -> None:
    node = load_manifest(EXAMPLES / "minimal.yaml").nodes[0]
    assert (node.replicas, node.reply_match, node.hedge, node.message_types, node.replica_hosts) == \
        (1, "header.stamp", "all", {}, ())


@pytest.mark.parametrize(("change", "expect"), [
    ("    replicas: 9\n", r"nodes\[0\]\.replicas: .*less than or equal to 8"),
    ("    replicas: 0\n", r"nodes\[0\]\.replicas: .*greater than or equal to 1"),
    ("    hedge: some\n", r"nodes\[0\]\.hedge"),
    ("    hedge: {delay_ms: 0}\n", r"nodes\[0\]\.hedge\.delay_ms: .*greater than or equal to 1"),
    ("    hedge: {delay: 5}\n", r"nodes\[0\]\.hedge"),
    ("    reply_match: Header-Stamp\n", r"nodes\[0\]\.reply_match: 'Header-Stamp' is not a message field"),
    ("    message_types: {/plan/path: PoseArray}\n", r"nodes\[0\]\.message_types: 'PoseArray' is not a ROS message"),
    ("    message_types: {plan: std_msgs/Float64}\n", r"nodes\[0\]\.message_types: 'plan' is not a ROS topic"),
    ("    topics: auto\n", r"nodes\[0\]\.topics: replicas: 2 needs its out topics listed"),
    ("    topics: {in: [/plan/request]}\n", r"nodes\[0\]\.topics: replicas: 2 needs its out topics listed"),
    ("    message_types: {/plan/path: std_msgs/Float64}\n",
     r"nodes\[0\]\.reply_match: /plan/path: std_msgs/Float64 has no std_msgs/Header, so replies cannot be matched"),
    ("    replica_hosts: [a]\n", r"nodes\[0\]\.replica_hosts: names 1 hosts for replicas: 2"),
    ("    replica_hosts: [a, a]\n", r"nodes\[0\]\.replica_hosts: names a host twice"),
])
def test_bad_replica_fields_are_one_line_naming_the_field(change: str, expect: str) -> None:
    key = change.split(":")[0]
    node = "".join(line + "\n" for line in PLANNER.splitlines() if not line.startswith(key + ":")) + change
    lines = problems(f"name: rep\ncloud: {{provider: local}}\nnodes:\n{node}")
    assert any(re.search(expect, line) for line in lines), lines
    assert all(line.startswith("fogiac.yaml:") and "\n" not in line for line in lines)


def test_a_field_the_reply_copies_replaces_the_header_and_headerless_types_pass() -> None:
    node = PLANNER.replace("geometry_msgs/PoseArray", "std_msgs/Float64") + "    reply_match: data\n"
    assert manifest(node=node).nodes[0].reply_match == "data"


def test_an_untyped_out_topic_is_accepted_with_a_one_line_warning() -> None:
    node = PLANNER.replace("    message_types: {/plan/path: geometry_msgs/PoseArray}\n", "")
    line = "node planner: replies on /plan/path are matched by header.stamp, unchecked (no type in message_types)"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # validating says nothing (it may still fail on another field)
        parsed = manifest(node=node)
    with pytest.warns(MatchUnchecked, match=re.escape(line)):
        plan = compile_plan(parsed)
    assert line in plan.notes
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a typed topic: nothing to warn about
        assert compile_plan(manifest()).notes == ()


def test_header_table_ros1_and_ros2_spellings() -> None:
    assert has_header("geometry_msgs/PoseArray") and has_header("sensor_msgs/msg/Image")
    assert has_header("my_msgs/GraspStamped") is True  # the convention
    # a reply that is a bare Header starts with the same bytes a headered message does: matched the same way
    assert has_header("std_msgs/Header") is True and has_header("std_msgs/msg/Header") is True
    assert has_header("std_msgs/Float64") is False
    assert has_header("std_msgs/Float64") is False and has_header("geometry_msgs/msg/Pose") is False
    assert has_header("my_msgs/Grasp") is None


def test_replica_hosts_must_name_cloud_hosts(tmp_path: Path) -> None:
    (tmp_path / "k").write_text("key")
    cloud = ("{provider: hosts, hosts: [{name: a, address: 10.0.0.1, user: u, key: k}, "
             "{name: b, address: 10.0.0.2, user: u, key: k}]}")
    with pytest.raises(ManifestError, match=r"nodes\[0\]\.replica_hosts: 'z' is not in cloud.hosts"):
        manifest(cloud, PLANNER + "    replica_hosts: [a, z]\n", base=tmp_path)
    with pytest.raises(ManifestError, match=r"nodes\[0\]\.replica_hosts: give host or replica_hosts, not both"):
        manifest(cloud, PLANNER + "    replica_hosts: [a, b]\n    host: a\n", base=tmp_path)


# ------------------------------------------------------------------ compile, per target


def test_local_gives_each_replica_a_sandbox_and_a_route_with_its_replica() -> None:
    node = PLANNER + "    hedge: {delay_ms: 40}\n"
    plan = compile_plan(manifest(node=node, others="  - name: solo\n    machine: t3.small\n"
                                                  "    image: ros:noetic-ros-core\n"))
    assert [h.name for h in plan.hosts] == ["planner-r1", "planner-r2", "solo"]
    assert [h.nodes for h in plan.hosts] == [("planner",), ("planner",), ("solo",)]
    routes = {r.host: r for r in plan.routes}
    stated = (("/plan/path", "geometry_msgs/PoseArray"),)  # the relay checks replies' types with them
    assert routes["planner-r1"].replica == Replica("planner", 0, 2, "header.stamp", "delayed", 0.04, stated)
    assert routes["planner-r2"].replica == Replica("planner", 1, 2, "header.stamp", "delayed", 0.04, stated)
    argv = replicas_argv("planner", [routes["planner-r1"], routes["planner-r2"]], stack="rep",
                         connect={"planner-r1": "127.0.0.1:1", "planner-r2": "127.0.0.1:2"},
                         master="http://127.0.0.1:11311", certs=Path("c"), folder=Path("f"))
    assert argv[argv.index("--type") + 1] == "/plan/path=geometry_msgs/PoseArray"
    assert routes["planner-r2"].to_cloud == ("/plan/request",) and routes["planner-r2"].to_edge == ("/plan/path",)
    assert routes["solo"].replica is None
    doc = plan.to_dict()
    assert doc["relay"][0]["replica"]["group"] == "planner" and "replica" not in doc["relay"][2]
    assert cost.replica_hosts(plan, "planner") == ["planner-r1", "planner-r2"]
    assert compile_plan(manifest(node=node)).digest() == compile_plan(manifest(node=node)).digest()


def test_unreplicated_plans_carry_none_of_the_new_keys() -> None:
    """Existing plans keep their documents (and digests): zone, notes and replica appear only when set."""
    for name in ("minimal", "motion-planning"):
        for target in ("aws", "local"):
            plan = compile_plan(load_manifest(EXAMPLES / f"{name}.yaml"), target=target)
            doc = plan.to_dict()
            assert "notes" not in doc and all("zone" not in h for h in doc["hosts"])
            assert all("replica" not in r for r in doc["relay"])
            assert all("zone" not in s for s in (doc["network"] or {}).get("subnets", ()))
            body = document(plan, (), manifest_path="m", manifest_sha256="0")
            assert "notes" not in body and all("zone" not in h and "replica" not in h for h in body["hosts"])
            assert all("replica_hosts" not in n for n in body["nodes"])


def test_hosts_target_puts_replicas_on_the_named_machines(tmp_path: Path) -> None:
    (tmp_path / "k").write_text("key")
    cloud = ("{provider: hosts, hosts: [{name: a, address: 10.0.0.1, user: u, key: k}, "
             "{name: b, address: 10.0.0.2, user: u, key: k}, {name: c, address: 10.0.0.3, user: u, key: k}]}")
    solo = "  - name: solo\n    machine: t3.small\n    image: ros:noetic-ros-core\n"
    plan = compile_plan(manifest(cloud, PLANNER + "    replica_hosts: [c, a]\n", solo, base=tmp_path))
    by = {h.name: h.nodes for h in plan.hosts}
    assert by == {"a": ("planner",), "b": ("solo",), "c": ("planner",)}
    assert {r.host: r.replica.index for r in plan.routes if r.replica} == {"c": 0, "a": 1}
    # unnamed: the spare machines in order, the unreplicated nodes on the rest
    plan = compile_plan(manifest(cloud, PLANNER, "  - name: solo\n    machine: t3.small\n    image: "
                                 "ros:noetic-ros-core\n    host: c\n", base=tmp_path))
    assert {r.host: r.replica.index for r in plan.routes if r.replica} == {"a": 0, "b": 1}
    with pytest.raises(PlanError, match=r"nodes.planner: host 'a' carries one of its replicas and solo too"):
        compile_plan(manifest(cloud, PLANNER + "    replica_hosts: [a, b]\n", solo + "    host: a\n", base=tmp_path))
    three = PLANNER.replace("replicas: 2", "replicas: 3")
    with pytest.raises(PlanError, match=r"nodes.planner: replicas: 3 needs 3 hosts of its own, cloud.hosts has 2"):
        compile_plan(manifest(cloud, three, solo + "    host: a\n", base=tmp_path))


AWS_CLOUD = "{provider: aws, region: us-west-2}"


def test_aws_two_replicas_two_zones_priced_twice() -> None:
    node = PLANNER + "    spot: true\n"
    plan = compile_plan(manifest(AWS_CLOUD, node))
    r1, r2 = plan.hosts
    assert (r1.name, r1.zone, r2.name, r2.zone) == ("planner-r1", "us-west-2a", "planner-r2", "us-west-2b")
    assert r1.spot and r2.spot
    # each instance says which host it is (status and drift find it by that, not by its node)
    assert (dict(r1.tags)["fogiac:host"], dict(r2.tags)["fogiac:replica"], dict(r2.tags)["fogiac:node"]) == \
        ("planner-r1", "2/2", "planner")
    each = on_demand("c5.large", "us-west-2")
    assert each > 0
    instances = [line for line in plan.cost if line.item.startswith("instance ")]
    assert [line.item for line in instances] == ["instance planner-r1 (c5.large, spot, us-west-2a)",
                                                 "instance planner-r2 (c5.large, spot, us-west-2b)"]
    assert sum(line.total for line in instances) == pytest.approx(2 * each)
    assert plan.hourly_usd == pytest.approx(2 * each + 0.15)  # and the Client VPN's two lines
    assert plan.spot_hourly_usd == pytest.approx(2 * (spot_price("c5.large", "us-west-2") or 0) + 0.15)
    assert plan.network is not None
    zones = {s.name: (s.zone, s.role, s.public) for s in plan.network.subnets}
    assert zones["hosts-us-west-2a"] == ("us-west-2a", "instances", True)
    assert zones["hosts-us-west-2b"] == ("us-west-2b", "instances", True)
    assert "planner: 2 replicas, planner-r1 in us-west-2a, planner-r2 in us-west-2b" in plan.notes
    assert any("2 machines priced" in n and "cost guard counts every one" in n for n in plan.notes)
    assert any("spot is safe with replicas" in n for n in plan.notes)
    body = document(plan, (), manifest_path="m", manifest_sha256="0")
    assert body["hosts"][0]["zone"] == "us-west-2a" and body["hosts"][1]["replica"] == "replica 2 of 2"
    assert body["nodes"][0]["replica_hosts"] == ["planner-r1", "planner-r2"]
    assert _node(body["nodes"][0]).startswith("planner on planner-r1, planner-r2")
    assert "replica 1 of 2, us-west-2a" in _host(body["hosts"][0])
    assert any("replica 2/2, us-west-2b" in box.lines for box in diagram.layout(plan).boxes)


def test_aws_skips_a_zone_that_does_not_offer_the_machine_and_says_so() -> None:
    cat = AWS.catalogue
    region = "us-east-1"
    offering = cat.zones_offering("t3.small", region)
    missing = [z for z in cat.region_zones(region) if z not in (offering or ())]
    assert offering and missing, "the catalogue's facts changed: pick another type with a zone that lacks it"
    count = min(len(offering), 8)
    node = PLANNER.replace("replicas: 2", f"replicas: {count}").replace("c5.large", "t3.small")
    plan = compile_plan(manifest("{provider: aws, region: us-east-1}", node))
    zones = [h.zone for h in plan.hosts]
    assert sorted(zones) == sorted(offering[:count]) and len(set(zones)) == count
    for zone in missing:
        assert f"planner: zone {zone} does not offer t3.small, skipped" in plan.notes
        assert zone not in zones


def test_aws_more_replicas_than_zones_share_zones_and_say_so() -> None:
    zones = AWS.catalogue.zones_offering("c5.large", "us-west-2")
    assert zones is not None and len(zones) < 8
    node = PLANNER.replace("replicas: 2", "replicas: 8")
    plan = compile_plan(manifest(AWS_CLOUD, node))
    assert len(plan.hosts) == 8 and {h.zone for h in plan.hosts} == set(zones)
    assert any("some share a zone" in n for n in plan.notes)


def test_aws_stack_program_puts_each_replica_in_its_zones_subnet() -> None:
    """The real network and compute programs under Pulumi's mocks: one subnet per used zone, each replica's
    instance in its zone's subnet, the unreplicated node in the plan's hosts subnet."""
    solo = "  - name: solo\n    machine: t3.small\n    image: ros:noetic-ros-core\n"
    offline = declare(compile_plan(manifest(AWS_CLOUD, PLANNER, solo)))
    subnets = {r.name: r.inputs for r in offline.of_type("aws:ec2/subnet:Subnet")}
    assert subnets["rep-dev-subnet-hosts-us-west-2a"]["availabilityZone"] == "us-west-2a"
    assert subnets["rep-dev-subnet-hosts-us-west-2b"]["availabilityZone"] == "us-west-2b"
    assert subnets["rep-dev-subnet-hosts"]["availabilityZone"] == "us-west-2a"
    instances = {r.name: r.inputs for r in offline.of_type("aws:ec2/instance:Instance")}
    assert instances["rep-dev-host-planner-r1"]["subnetId"] == "<rep-dev-subnet-hosts-us-west-2a.id>"
    assert instances["rep-dev-host-planner-r2"]["subnetId"] == "<rep-dev-subnet-hosts-us-west-2b.id>"
    assert instances["rep-dev-host-solo"]["subnetId"] == "<rep-dev-subnet-hosts.id>"
    assert all(i["instanceType"] == "c5.large" for n, i in instances.items() if "planner" in n)
    associations = {r.name for r in offline.of_type("aws:ec2/routeTableAssociation:RouteTableAssociation")}
    assert {"rep-dev-rta-hosts-us-west-2a", "rep-dev-rta-hosts-us-west-2b"} <= associations


def test_aws_small_vpc_without_room_for_the_zones_subnets_is_refused() -> None:
    text = (f"name: rep\ncloud: {AWS_CLOUD}\nnetwork: {{vpc_cidr: 10.10.0.0/24}}\nnodes:\n{PLANNER}")
    with pytest.raises(PlanError, match=r"network.vpc_cidr: 10.10.0.0/24 has room for 2 subnets"):
        compile_plan(parse_manifest(text, source="fogiac.yaml"))


def test_catalogue_zones_round_trip_and_an_older_catalogue_without_them(tmp_path: Path) -> None:
    """What the refresh writes (type -> region -> zones) is what the catalogue answers; a catalogue written
    before zones were listed answers None, and placement then assumes zones and says so."""
    from fogiac.targets.aws.catalogue import read
    from fogiac.targets.aws.refresh import Builder

    b = Builder()
    b.add_hardware({"InstanceType": "c5.large", "VCpuInfo": {"DefaultVCpus": 2}, "MemoryInfo": {"SizeInMiB": 4096},
                    "ProcessorInfo": {"SupportedArchitectures": ["x86_64"]}}, b.source(
        AWS.catalogue.sources[0]))
    for region in ("us-west-2", "eu-west-1"):
        b.offer("c5.large", region)
    for zone in ("us-west-2c", "us-west-2a"):
        b.zone("c5.large", zone)
    path = b.write(tmp_path / "cat.json.gz")
    cat = read(path)
    assert cat.zones_offering("c5.large", "us-west-2") == ("us-west-2a", "us-west-2c")
    assert cat.region_zones("us-west-2") == ("us-west-2a", "us-west-2c")
    assert cat.zones_offering("c5.large", "eu-west-1") is None  # no zone facts there
    b.zones.clear()
    assert read(b.write(tmp_path / "old.json.gz")).zones_offering("c5.large", "us-west-2") is None
    shipped = AWS.catalogue  # the shipped one lists zones from moto's per-zone offerings
    assert shipped.zones_offering("c5.large", "us-west-2") == ("us-west-2a", "us-west-2b", "us-west-2c",
                                                                "us-west-2d")


def test_a_catalogue_without_zones_assumes_them_and_says_so(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The user's own catalogue (``fogiac catalog update``) written without zone facts: the replicas go to
    the plan's zone and the next letters, and the plan says preflight checks them."""
    import gzip
    import json
    from importlib import resources

    from fogiac.targets.aws.manifest import user_catalogue

    monkeypatch.setenv("FOGIAC_STATE_DIR", str(tmp_path))
    raw = json.loads(gzip.decompress(resources.files("fogiac").joinpath(
        "targets/aws/data/catalogue.json.gz").read_bytes()))
    del raw["zones"]
    own = user_catalogue()
    own.parent.mkdir(parents=True)
    own.write_bytes(gzip.compress(json.dumps(raw).encode()))
    plan = compile_plan(manifest("{provider: aws, region: us-west-2, zone: us-west-2c}", PLANNER))
    assert [h.zone for h in plan.hosts] == ["us-west-2c", "us-west-2a"]
    assert ("planner: the catalogue lists no zones of us-west-2; replicas assumed in us-west-2c, us-west-2a "
            "(`fogiac up` checks them)") in plan.notes


def test_preflight_checks_each_replicas_zone_against_what_ec2_offers() -> None:
    from fogiac.targets.aws.api import choose_zone

    solo = "  - name: solo\n    machine: t3.small\n    image: ros:noetic-ros-core\n"
    plan = compile_plan(manifest(AWS_CLOUD, PLANNER, solo))
    problems: list[str] = []
    offered = {"us-west-2a": {"c5.large", "t3.small"}, "us-west-2b": {"t3.small"}}
    assert choose_zone(plan, offered, problems) == "us-west-2a"
    assert problems == ["planner-r2: zone us-west-2b does not offer c5.large (replicas go to zones of their own; "
                        "`fogiac catalog update` refreshes which zones offer what)"]
    problems.clear()
    offered["us-west-2b"].add("c5.large")
    assert choose_zone(plan, offered, problems) == "us-west-2a" and problems == []
