"""Zenoh router configurations, rendered from a Plan's routes: pure functions, dicts out.

The cloud router of a host listens twice: mutual TLS on the address the edge dials, and plain
TCP on loopback for the host's own nodes (``RMW_IMPLEMENTATION=rmw_zenoh_cpp`` connects to
``localhost:7447``). Access control tells the two apart by link protocol and the edge
certificate's common name, and lets the edge see only the manifest's topics:

- edge -> cloud (a node's ``in``): the edge may put them, the cloud may declare subscribers to them;
- cloud -> edge (a node's ``out``): the cloud may put them, the edge may declare subscribers;
- ``relay.topics`` (direction unknown) both ways; everything else denied, in both flows.

Liveliness tokens under ``@ros2_lv`` (rmw_zenoh's graph: node and endpoint names, no data) pass
both ways, so ``ros2 node list`` on the robot shows the cloud nodes.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from fogiac.plan.model import Route

ROUTER_PORT = 7448  # the cloud router's mutual-TLS port for the edge (7447, rmw_zenoh's default, stays local)
LOCAL_PORT = 7447  # rmw_zenoh's default router port: where nodes on the same machine connect

GRAPH_KEYS = ("@ros2_lv/**",)  # rmw_zenoh's liveliness tokens: the ROS graph, no payloads
_DATA = ["put", "delete"]
_GRAPH = ["liveliness_token", "declare_liveliness_subscriber", "liveliness_query"]
# rmw_zenoh's nodes are peers that find each other through their router's gossip (one hop, never
# passed on); a router itself never dials what it hears, so nothing reaches across to the other side.
_GOSSIP = {"enabled": True, "multihop": False, "target": {"router": ["peer"], "peer": ["router", "peer"]},
           "autoconnect": {"router": [], "peer": ["router", "peer"]}}
_RETRY = {"period_init_ms": 250, "period_max_ms": 2000, "period_increase_factor": 2}


@dataclass(frozen=True)
class TlsFiles:
    """Where one router's PEM files lie on its machine: fogiac's CA, its certificate and key."""

    ca: str
    cert: str
    key: str


def topic_key(topic: str) -> str:
    """rmw_zenoh's data key for ``topic`` in any domain, any type: ``<domain>/<topic>/<type>/<hash>``.

    Exactly two chunks follow the topic, so allowing ``/camera`` never allows ``/camera/secret``.
    """
    return f"*/{topic.strip('/')}/*/*"


def _keys(topics: Iterable[str], prefix: str = "") -> list[str]:
    return [prefix + topic_key(t) for t in sorted(set(topics))]


def replica_keys_prefix(route: Route) -> str:
    """Where a replica's data crosses: under ``fogiac/replica/<group>/<index>/`` (the host's replica process
    renames to and from its nodes' plain keys; :mod:`fogiac.net.zenoh.replicas`), or plain ("")."""
    replica = route.replica
    return "" if replica is None else f"fogiac/replica/{replica.group}/{replica.index}/"


def _rule(rule_id: str, flow: str, messages: list[str], keys: list[str]) -> dict[str, Any]:
    return {"id": rule_id, "permission": "allow", "flows": [flow], "messages": messages, "key_exprs": keys}


def access_control(route: Route, *, edge_name: str) -> dict[str, Any]:
    """Deny by default; the host's own nodes (TCP on loopback) may do anything among themselves. A replica's
    host lets only its prefixed keys cross, so the edge's merge sees every copy of a reply, the robot none."""
    prefix = replica_keys_prefix(route)
    to_cloud = _keys(route.to_cloud + route.listed, prefix)
    to_edge = _keys(route.to_edge + route.listed, prefix)
    rules = [_rule("local", flow, _DATA + ["declare_subscriber", "query", "reply", "declare_queryable"] + _GRAPH,
                   ["**"]) for flow in ("ingress", "egress")]
    rules[0]["id"], rules[1]["id"] = "local-in", "local-out"
    rules.append(_rule("graph-in", "ingress", _GRAPH, list(GRAPH_KEYS)))
    rules.append(_rule("graph-out", "egress", _GRAPH, list(GRAPH_KEYS)))
    if to_cloud:
        rules.append(_rule("to-cloud-data", "ingress", _DATA, to_cloud))
        rules.append(_rule("to-cloud-interest", "egress", ["declare_subscriber"], to_cloud))
    if to_edge:
        rules.append(_rule("to-edge-data", "egress", _DATA, to_edge))
        rules.append(_rule("to-edge-interest", "ingress", ["declare_subscriber"], to_edge))
    edge_rules = [r["id"] for r in rules if not r["id"].startswith("local")]
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": [
            {"id": "host-nodes", "link_protocols": ["tcp"], "interfaces": ["lo"]},
            {"id": "edge", "link_protocols": ["tls"], "cert_common_names": [edge_name]},
        ],
        "policies": [
            {"id": "host-nodes", "rules": ["local-in", "local-out"], "subjects": ["host-nodes"]},
            {"id": "edge", "rules": edge_rules, "subjects": ["edge"]},
        ],
    }


def _tls(files: TlsFiles, *, listen: bool) -> dict[str, Any]:
    side = "listen" if listen else "connect"
    return {
        "root_ca_certificate": files.ca,
        f"{side}_private_key": files.key,
        f"{side}_certificate": files.cert,
        "enable_mtls": True,
        "verify_name_on_connect": True,
    }


def _base(*, listen: Sequence[str], connect: Sequence[str], tls: dict[str, Any]) -> dict[str, Any]:
    return {
        "mode": "router",
        "listen": {"endpoints": list(listen)},
        "connect": {"endpoints": list(connect), "timeout_ms": -1, "exit_on_failure": False, "retry": dict(_RETRY)},
        "scouting": {"multicast": {"enabled": False}, "gossip": dict(_GOSSIP)},
        "transport": {"link": {"tls": tls}},
        "adminspace": {"enabled": False},
    }


def cloud_router(route: Route, *, listen_host: str, tls: TlsFiles, edge_name: str,
                 local_port: int = LOCAL_PORT) -> dict[str, Any]:
    """The router on ``route.host``: mutual TLS for the edge on ``listen_host``, loopback for its nodes."""
    config = _base(listen=(f"tls/{listen_host}:{route.port}", f"tcp/127.0.0.1:{local_port}"), connect=(),
                   tls=_tls(tls, listen=True))
    config["access_control"] = access_control(route, edge_name=edge_name)
    return config


def edge_router(cloud: Sequence[tuple[str, int]], *, tls: TlsFiles, local_port: int = LOCAL_PORT) -> dict[str, Any]:
    """The robot's router: dials every cloud router, listens on loopback only (for the robot's nodes)."""
    return _base(listen=(f"tcp/127.0.0.1:{local_port}",), connect=[f"tls/{host}:{port}" for host, port in cloud],
                 tls=_tls(tls, listen=False))

