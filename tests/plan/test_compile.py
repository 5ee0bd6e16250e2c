"""compile_plan: pure and deterministic, least-privilege rules, the right hosts and costs."""

from __future__ import annotations

import ipaddress
from pathlib import Path

import pytest

from fogiac.plan.compile import compile_plan
from fogiac.plan.cost import node_row
from fogiac.plan.model import check_ingress
from fogiac.targets.aws.placement import NVIDIA, UBUNTU
from fogiac.errors import PlanError
from fogiac.manifest.schema import load_manifest, parse_manifest
from fogiac.plan.model import OPERATOR, RELAY_PORT, Rule, SecurityGroup

from tests.conftest import EXAMPLES


def example(name: str):
    return load_manifest(EXAMPLES / f"{name}.yaml")


def test_same_manifest_same_plan_byte_for_byte() -> None:
    first = compile_plan(example("motion-planning"))
    second = compile_plan(load_manifest(EXAMPLES / "motion-planning.yaml"))
    assert first == second
    assert first.digest() == second.digest()
    assert compile_plan(example("motion-planning"), environment="prod").digest() != first.digest()


def test_network_layout_and_vpn() -> None:
    plan = compile_plan(example("motion-planning"))
    assert plan.stack == "motion-planning-dev"
    assert plan.zone == "us-west-2a" and not plan.zone_chosen
    assert plan.network is not None
    assert [(s.name, s.cidr, s.role) for s in plan.network.subnets] == [
        ("hosts", "10.10.0.0/24", "instances"),
        ("vpn", "10.10.1.0/24", "vpn"),
    ]
    assert plan.vpn is not None
    assert plan.vpn.client_cidr == "10.200.0.0/22"
    assert plan.vpn.authorize_cidr == "10.10.0.0/16"
    assert plan.vpn.server_name == "server.motion-planning-dev.fogiac"
    assert plan.vpn.split_tunnel


def test_small_vpc_gets_slash_27_subnets() -> None:
    manifest = parse_manifest(
        "name: s\nnetwork: {vpc_cidr: 10.1.0.0/26}\nnodes: [{name: a, machine: t3.micro, image: x}]\n"
    )
    plan = compile_plan(manifest)
    assert [s.cidr for s in plan.network.subnets] == ["10.1.0.0/27", "10.1.0.32/27"]  # type: ignore[union-attr]


def test_vpn_mode_rules_are_least_privilege() -> None:
    plan = compile_plan(example("motion-planning"))
    hosts = plan.security_groups[0]
    ssh = [r for r in hosts.ingress if r.from_port == 22]
    assert [r.cidr for r in ssh] == [OPERATOR]
    others = {r.cidr for r in hosts.ingress if r.from_port != 22}
    assert others == {"10.10.0.0/16", "10.200.0.0/22"}
    relay = [r for r in hosts.ingress if r.from_port == RELAY_PORT]
    assert {r.cidr for r in relay} == {"10.10.0.0/16", "10.200.0.0/22"}
    vpn = plan.security_groups[1]
    assert vpn.ingress == () and [r.cidr for r in vpn.egress] == ["10.10.0.0/16"]
    for group in plan.security_groups:
        check_ingress(group.name, group.ingress)


def test_a_security_group_open_to_the_world_cannot_be_made() -> None:
    """The invariant holds where a group is made, whoever makes it (a target's placement, a plug-in's):
    compile_plan no longer re-checks the groups a placement hands back."""
    for cidr in ("0.0.0.0/0", "::/0"):
        with pytest.raises(PlanError, match=rf"^security group 'hosts' would accept {cidr} on port 22$"):
            SecurityGroup("hosts", "ssh", (Rule("tcp", 22, 22, cidr, "ssh"),), ())
    with pytest.raises(PlanError, match=r"^security group 'hosts': 'nowhere' is not a CIDR$"):
        SecurityGroup("hosts", "ssh", (Rule("tcp", 22, 22, "nowhere", "ssh"),), ())
    # egress may go anywhere, and the operator's address is resolved later (the firewall stack checks it then)
    SecurityGroup("hosts", "ssh", (Rule("tcp", 22, 22, OPERATOR, "ssh"),), (Rule("-1", 0, 0, "0.0.0.0/0", "out"),))


def test_proxy_mode_opens_the_relay_to_ssh_from_only() -> None:
    plan = compile_plan(example("proxy"))
    assert plan.vpn is None and plan.mode == "proxy"
    assert [g.name for g in plan.security_groups] == ["hosts"]
    relay = [r for r in plan.security_groups[0].ingress if r.from_port == RELAY_PORT]
    assert {r.cidr for r in relay} == {"10.10.0.0/16", "198.51.100.0/24"}
    for rule in plan.security_groups[0].ingress:
        assert rule.cidr == OPERATOR or ipaddress.ip_network(rule.cidr).prefixlen > 0
    assert plan.routes[0].connect_via == "public"


def test_a_ros2_stack_opens_only_ssh_and_the_zenoh_router() -> None:
    """No ROS 1 master or node ports on a ROS 2 host: its traffic crosses only the router's port."""
    plan = compile_plan(example("ros2-zenoh"))
    ports = {(r.from_port, r.to_port, r.cidr) for r in plan.security_groups[0].ingress}
    assert ports == {(22, 22, "198.51.100.0/24"), (7448, 7448, "10.10.0.0/16"), (7448, 7448, "198.51.100.0/24")}
    ros1 = {(r.from_port, r.to_port) for r in compile_plan(example("proxy")).security_groups[0].ingress}
    assert {(11311, 11311), (32768, 60999)} <= ros1  # ROS 1 over a VPN reaches the master and its nodes


def test_hosts_hardware_image_and_tags() -> None:
    grasp = compile_plan(example("grasp-planning"))
    (host,) = grasp.hosts
    assert (host.machine, host.gpus, host.vcpus, host.image) == ("g4dn.xlarge", 1, 4, NVIDIA)
    assert ("fogiac:stack", "grasp-planning-dev") in host.tags
    assert ("fogiac:node", "grasp") in host.tags
    motion = compile_plan(example("motion-planning"))
    assert motion.hosts[0].image == UBUNTU and motion.hosts[0].vcpus == 96
    assert ("project", "fogros-demo") in motion.tags


def test_cost_counts_instances_and_client_vpn() -> None:
    plan = compile_plan(example("motion-planning"))
    assert [(c.item, c.usd_per_hour) for c in plan.cost] == [
        ("instance planner (c5.24xlarge)", 4.08),
        ("Client VPN subnet association", 0.10),
        ("Client VPN connection (the edge)", 0.05),
    ]
    assert plan.hourly_usd == pytest.approx(4.23)
    assert compile_plan(example("proxy")).hourly_usd == pytest.approx(1.36)


def test_relay_routes_follow_node_topics_and_compression() -> None:
    plan = compile_plan(example("grasp-planning"))
    (route,) = plan.routes
    assert route.to_cloud == ("/depth/camera_info", "/depth/image")
    assert route.to_edge == ("/grasp", "/grasp/compute_time", "/grasp/quality")
    assert route.compression == (("/depth/image", "zstd"),)
    assert not route.auto and route.connect_via == "private"


def test_local_target_has_no_cloud_resources_and_costs_nothing() -> None:
    plan = compile_plan(example("motion-planning"), target="local")
    assert plan.network is None and plan.vpn is None and plan.security_groups == ()
    assert plan.hourly_usd == 0
    assert [h.address for h in plan.hosts] == ["127.0.0.1"]
    assert plan.routes[0].connect_via == "loopback"


def test_hosts_target_places_nodes_and_checks_gpus(tmp_path: Path) -> None:
    (tmp_path / "id").write_text("k")
    text = (
        "name: lab\ncloud:\n  provider: hosts\n  hosts:\n"
        "    - {name: gpu1, address: 10.1.2.3, key: id, gpus: 1}\n"
        "    - {name: cpu1, address: 10.1.2.4, key: id}\n"
        "nodes:\n  - {name: a, machine: g4dn.xlarge, gpu: true, image: x, host: gpu1}\n"
        "  - {name: b, machine: c5.large, image: y}\n  - {name: c, machine: c5.large, image: z}\n"
    )
    plan = compile_plan(parse_manifest(text, base=tmp_path))
    assert [(h.name, h.nodes) for h in plan.hosts] == [("gpu1", ("a", "c")), ("cpu1", ("b",))]
    assert plan.hosts[0].key == str(tmp_path / "id")
    bad = text.replace("host: gpu1", "host: cpu1")
    with pytest.raises(PlanError, match=r"^nodes.a: needs a GPU but host 'cpu1' has gpus: 0$"):
        compile_plan(parse_manifest(bad, base=tmp_path))


def test_hosts_target_needs_hosts() -> None:
    with pytest.raises(PlanError, match=r"^cloud.hosts: the hosts target needs at least one machine$"):
        compile_plan(example("minimal"), target="hosts")


def test_unknown_target_lists_the_valid_ones() -> None:
    with pytest.raises(PlanError, match=r"^unknown target 'gcp'; valid: aws, hosts, local$"):
        compile_plan(example("minimal"), target="gcp")


def test_plan_table_says_what_each_kind_of_node_runs(tmp_path: Path) -> None:
    (tmp_path / "app").mkdir()
    (tmp_path / "app" / "Dockerfile").write_text("FROM ros:noetic-ros-core\n")
    text = (
        "name: kinds\ncloud: {provider: local}\nnodes:\n"
        "  - {name: built, machine: c5.large, build: {context: app}}\n"
        "  - {name: pulled, machine: c5.large, image: 'ros:noetic-ros-core'}\n"
        "  - {name: cmd, machine: c5.large, command: [rostopic, pub, /chatter, std_msgs/String, 'data: hi there']}\n"
        "  - {name: planner, machine: c5.large, workload: motion_planning}\n"
    )
    rows = {row["name"]: row["runs"] for row in map(node_row, compile_plan(parse_manifest(text, base=tmp_path)).nodes)}
    assert rows == {"built": f"build {tmp_path / 'app'} (Dockerfile)", "pulled": "ros:noetic-ros-core",
                    "cmd": "rostopic pub /chatter std_msgs/String 'data: hi there'", "planner": "workload motion_planning"}
