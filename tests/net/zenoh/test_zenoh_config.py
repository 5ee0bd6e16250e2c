"""Zenoh's part of the plan and its rendered router configs: pure, no router needed."""

from __future__ import annotations

from pathlib import Path

import pytest
import tomllib

from fogiac.errors import ManifestError, PlanError
from fogiac.manifest.schema import load_manifest, parse_manifest
from fogiac.net import middleware
from fogiac.net.zenoh.config import TlsFiles, access_control, cloud_router, edge_router, topic_key
from fogiac.net.zenoh.middleware import ROUTER_PORT
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import OPERATOR
from tests.conftest import EXAMPLES, REPO
from tests.net.zenoh.lab import route

FILES = TlsFiles(ca="/etc/fogiac/ca.pem", cert="/etc/fogiac/router.pem", key="/etc/fogiac/router.key")


def test_each_distro_has_one_middleware() -> None:
    assert middleware.for_distro("noetic").name == "relay"
    assert {middleware.for_distro(d).name for d in ("humble", "jazzy", "kilted")} == {"zenoh"}
    assert set(middleware.distros()) == {"noetic", "humble", "jazzy", "kilted"}
    with pytest.raises(PlanError, match="no middleware serves ROS 'iron'; served: humble, jazzy, kilted, noetic"):
        middleware.for_distro("iron")


def test_a_topic_key_matches_exactly_that_topic() -> None:
    assert topic_key("/camera/image") == "*/camera/image/*/*"  # domain / topic / type / type hash


def test_access_control_denies_by_default_and_allows_each_topic_in_its_direction_only() -> None:
    acl = access_control(route(7448, to_cloud=("/scan",), to_edge=("/plan",)), edge_name="edge.x")
    assert acl["enabled"] and acl["default_permission"] == "deny"
    rules = {r["id"]: r for r in acl["rules"]}
    assert rules["edge-data-in"] == {"id": "edge-data-in", "permission": "allow", "flows": ["ingress"],
                                     "messages": ["put", "delete"], "key_exprs": ["*/scan/*/*"]}
    assert rules["edge-data-out"]["flows"] == ["egress"] and rules["edge-data-out"]["key_exprs"] == ["*/plan/*/*"]
    assert rules["edge-interest-out"]["messages"] == ["declare_subscriber"]
    # the graph: the robot's publisher of /scan and subscriber of /plan in, the cloud's mirror image out
    assert rules["edge-graph-in"]["messages"] == ["liveliness_token"]
    assert rules["edge-graph-in"]["key_exprs"] == ["@ros2_lv/*/*/*/*/MP/*/*/*/%scan/*/*/*",
                                                   "@ros2_lv/*/*/*/*/MS/*/*/*/%plan/*/*/*"]
    assert rules["edge-graph-out"]["key_exprs"] == ["@ros2_lv/*/*/*/*/MP/*/*/*/%plan/*/*/*",
                                                    "@ros2_lv/*/*/*/*/MS/*/*/*/%scan/*/*/*"]
    edge = next(p for p in acl["policies"] if p["subjects"] == ["edge"])
    keys = {k for r in acl["rules"] if r["id"] in edge["rules"] for k in r["key_exprs"]}
    assert {k for k in keys if not k.startswith("@ros2_lv/")} == {"*/scan/*/*", "*/plan/*/*"}  # no wildcard
    assert {m for r in acl["rules"] if r["id"] in edge["rules"] for m in r["messages"]} == {
        "put", "delete", "declare_subscriber", "liveliness_token"}  # no query, reply, liveliness query
    subjects = {s["id"]: s for s in acl["subjects"]}
    assert subjects["edge"] == {"id": "edge", "link_protocols": ["tls"], "cert_common_names": ["edge.x"]}


def test_the_cloud_router_listens_with_mutual_tls_and_the_edge_router_only_dials_out() -> None:
    cloud = cloud_router(route(7448), listen_host="10.10.0.5", tls=FILES, edge_name="edge.x", local_port=7447)
    assert cloud["mode"] == "router"
    assert cloud["listen"]["endpoints"] == ["tls/10.10.0.5:7448", "tcp/127.0.0.1:7447"]
    assert cloud["transport"]["link"]["tls"] == {
        "root_ca_certificate": FILES.ca, "listen_private_key": FILES.key, "listen_certificate": FILES.cert,
        "enable_mtls": True, "verify_name_on_connect": True,
    }
    policy = [("a.router.s.fogiac", route(7448, to_cloud=("/scan",), to_edge=("/plan",))),
              ("b.router.s.fogiac", route(7448, to_cloud=("/imu",), to_edge=()))]
    edge = edge_router([("10.10.0.5", 7448), ("10.10.0.6", 7448)], tls=FILES, local_port=7447, policy=policy)
    assert edge["connect"]["endpoints"] == ["tls/10.10.0.5:7448", "tls/10.10.0.6:7448"]
    assert edge["listen"]["endpoints"] == ["tcp/127.0.0.1:7447"]  # for the robot's nodes, nothing else
    assert edge["transport"]["link"]["tls"]["connect_certificate"] == FILES.cert
    acl = edge["access_control"]  # the mirror image of each cloud router's, that router known by its name
    assert acl["default_permission"] == "deny"
    assert [s for s in acl["subjects"] if s["link_protocols"] == ["tls"]] == [
        {"id": "cloud0", "link_protocols": ["tls"], "cert_common_names": ["a.router.s.fogiac"]},
        {"id": "cloud1", "link_protocols": ["tls"], "cert_common_names": ["b.router.s.fogiac"]}]
    rules = {r["id"]: r for r in acl["rules"]}
    assert rules["cloud0-data-in"]["key_exprs"] == ["*/plan/*/*"] and rules["cloud0-data-out"]["key_exprs"] == [
        "*/scan/*/*"]
    assert rules["cloud1-data-out"]["key_exprs"] == ["*/imu/*/*"] and "cloud1-data-in" not in rules
    for config in (cloud, edge):
        assert config["scouting"]["multicast"]["enabled"] is False
        assert config["scouting"]["gossip"]["autoconnect"]["router"] == []  # routers dial only what they are told


def test_a_ros2_plan_says_zenoh_and_opens_the_router_port_to_ssh_from_or_the_vpn_only() -> None:
    manifest = load_manifest(EXAMPLES / "ros2-zenoh.yaml")
    plan = compile_plan(manifest)
    assert plan.middleware == "zenoh" and plan.ros_distro == "jazzy"
    assert [(r.port, r.to_cloud, r.to_edge) for r in plan.routes] == [
        (ROUTER_PORT, ("/camera/image_raw",), ("/detections", "/overlay"))]
    rules = [r for g in plan.security_groups for r in g.ingress if r.from_port <= ROUTER_PORT <= r.to_port]
    assert {r.cidr for r in rules} == {"10.10.0.0/16", "198.51.100.0/24"}  # proxy: the VPC and ssh_from
    vpn = compile_plan(manifest.model_copy(update={"network": manifest.network.model_copy(
        update={"mode": "vpn", "ssh_from": "auto"})}))
    rules = [r for g in vpn.security_groups for r in g.ingress if r.from_port <= ROUTER_PORT <= r.to_port]
    assert {r.cidr for r in rules} == {"10.10.0.0/16", "10.200.0.0/22"}  # the VPC and the VPN's clients
    assert OPERATOR not in {r.cidr for r in rules}


def test_ros2_nodes_must_list_their_topics(tmp_path: Path) -> None:
    text = "name: r\nros:\n  distro: humble\nnodes:\n  - name: a\n    machine: c5.large\n    image: x\n"
    with pytest.raises(ManifestError, match=r"<manifest>:5: nodes\[0\].topics: ROS humble crosses through zenoh"):
        parse_manifest(text)


def test_the_hosts_router_requirement_is_pyprojects_pin() -> None:
    extras = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    (pin,) = middleware.get("zenoh").host_requirements
    assert pin in extras["ros2"] and pin.startswith("eclipse-zenoh==")
    assert middleware.get("relay").host_requirements == ()


def test_a_fleets_cloud_router_lets_each_robot_only_its_namespace_and_a_revoked_one_nothing() -> None:
    robots = {"r1": "r1.edge.router.s.fogiac", "r2": "r2.edge.router.s.fogiac", "r3": "r3.edge.router.s.fogiac"}
    acl = cloud_router(route(7448), listen_host="10.0.0.5", tls=FILES, robots=robots, revoked=("r3",))["access_control"]
    assert acl["default_permission"] == "deny"
    names = {s["id"]: s.get("cert_common_names") for s in acl["subjects"]}
    assert names == {"host-nodes": None, "robot-r1": [robots["r1"]], "robot-r2": [robots["r2"]]}
    rules = {r["id"]: r for r in acl["rules"]}
    for policy in acl["policies"][1:]:
        robot = policy["id"].removeprefix("robot-")
        keys = {k for rule in policy["rules"] for k in rules[rule]["key_exprs"]}
        assert keys == {f"*/{robot}/**", f"@ros2_lv/*/*/*/*/MP/*/*/*/%{robot}%$*/*/*/*",
                        f"@ros2_lv/*/*/*/*/MS/*/*/*/%{robot}%$*/*/*/*"}
    assert not [r for r in acl["rules"] if "r3" in r["id"]]


def test_a_cloud_router_names_its_edge_or_its_fleet() -> None:
    with pytest.raises(ValueError, match="edge_name.*or a fleet"):
        cloud_router(route(7448), listen_host="10.0.0.5", tls=FILES)
