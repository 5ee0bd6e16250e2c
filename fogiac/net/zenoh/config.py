"""Zenoh router configurations, rendered from a Plan's routes: pure functions, dicts out.

The cloud router of a host listens twice: mutual TLS on the address the edge dials, and plain
TCP on loopback for the host's own nodes (``RMW_IMPLEMENTATION=rmw_zenoh_cpp`` connects to
``localhost:7447``). Access control tells the two apart by link protocol and the edge
certificate's common name, and lets the edge see only the manifest's topics:

- edge -> cloud (a node's ``in``): the edge may put them, the cloud may declare subscribers to them;
- cloud -> edge (a node's ``out``): the cloud may put them, the edge may declare subscribers;
- ``relay.topics`` (direction unknown) both ways; everything else denied, in both flows.

The edge router holds the mirror image towards each cloud router it dials (recognised by the
certificate's common name): from the cloud only the ``out`` keys' data and subscriptions to the
``in`` keys; to the cloud only the ``in`` keys' data and subscriptions to the ``out`` keys. So a
cloud host whose router lost its access control (root there can remove it) still reaches no
unlisted robot topic and puts nothing unlisted on the robot.

Liveliness (rmw_zenoh's graph, ``@ros2_lv``) crosses only as the listed topics need it, one
token per endpoint: a publisher's (``MP``) token of a topic towards its subscribers' side, a
subscriber's (``MS``) towards its publishers' side. Node tokens, service and client tokens, the
tokens of any other topic, liveliness subscriptions and queries, and every query or reply stay on
their side: neither side learns the other's node names or unlisted topics, nor forges them.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from fogiac.plan.model import Route

ROUTER_PORT = 7448  # the cloud router's mutual-TLS port for the edge (7447, rmw_zenoh's default, stays local)
LOCAL_PORT = 7447  # rmw_zenoh's default router port: where nodes on the same machine connect

GRAPH_SPACE = "@ros2_lv"  # rmw_zenoh's liveliness tokens: the ROS graph, no payloads
_DATA = ["put", "delete"]
_GRAPH = ["liveliness_token", "declare_liveliness_subscriber", "liveliness_query"]
PUBLISHER, SUBSCRIBER = "MP", "MS"  # rmw_zenoh's entity kinds in a liveliness token
# rmw_zenoh's nodes are peers that find each other through their router's gossip (one hop, never
# passed on); a router itself never dials what it hears, so nothing reaches across to the other side.
_GOSSIP = {"enabled": True, "multihop": False, "target": {"router": ["peer"], "peer": ["router", "peer"]},
           "autoconnect": {"router": [], "peer": ["router", "peer"]}}
# How a router redials a link that dropped or never came up: soon at first, then every 2 s at most (an edge
# whose cloud host is down, a fleet front whose core is restarting), never giving up.
CONNECT_RETRY = {"period_init_ms": 250, "period_max_ms": 2000, "period_increase_factor": 2}


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
    """Where a replica's data crosses: under ``fogiac/replica/<group>/<number>/`` (``index + 1``, as
    :func:`fogiac.net.zenoh.replicas.replica_prefix` names it: the host's replica process renames to and
    from its nodes' plain keys), or plain ("")."""
    replica = route.replica
    return "" if replica is None else f"fogiac/replica/{replica.group}/{replica.index + 1}/"


def graph_key(topic: str, kind: str) -> str:
    """rmw_zenoh's liveliness token of one publisher (``MP``) or subscriber (``MS``) of ``topic``:
    ``@ros2_lv/<domain>/<zid>/<node>/<entity>/<kind>/<enclave>/<namespace>/<node name>/<topic>/<type>/<hash>/<qos>``,
    the topic's slashes mangled to ``%``; exactly one chunk per field, so nothing else matches."""
    mangled = "%" + topic.strip("/").replace("/", "%")
    return f"{GRAPH_SPACE}/*/*/*/*/{kind}/*/*/*/{mangled}/*/*/*"


def graph_keys(*, publishers: Iterable[str], subscribers: Iterable[str]) -> list[str]:
    """The tokens that may cross one way: the publishers of what crosses, the subscribers of what comes back."""
    return ([graph_key(t, PUBLISHER) for t in sorted(set(publishers))]
            + [graph_key(t, SUBSCRIBER) for t in sorted(set(subscribers))])


def _link_rules(prefix: str, *, receive: list[str], send: list[str], keys: str = "") -> list[dict[str, Any]]:
    """One side's rules for a link, in its own flows: data it receives (``ingress``) and sends (``egress``),
    subscriptions declared the other way, and the publisher/subscriber tokens that go with them. A replica's
    link carries its data keys under ``keys`` (its prefix: :func:`replica_keys_prefix`), its tokens as they are."""
    rules = []
    if receive:
        rules.append(_rule(f"{prefix}-data-in", "ingress", _DATA, _keys(receive, keys)))
        rules.append(_rule(f"{prefix}-interest-out", "egress", ["declare_subscriber"], _keys(receive, keys)))
    if send:
        rules.append(_rule(f"{prefix}-data-out", "egress", _DATA, _keys(send, keys)))
        rules.append(_rule(f"{prefix}-interest-in", "ingress", ["declare_subscriber"], _keys(send, keys)))
    tokens_in = graph_keys(publishers=receive, subscribers=send)
    tokens_out = graph_keys(publishers=send, subscribers=receive)
    if tokens_in:
        rules.append(_rule(f"{prefix}-graph-in", "ingress", ["liveliness_token"], tokens_in))
        rules.append(_rule(f"{prefix}-graph-out", "egress", ["liveliness_token"], tokens_out))
    return rules


def _rule(rule_id: str, flow: str, messages: list[str], keys: list[str]) -> dict[str, Any]:
    return {"id": rule_id, "permission": "allow", "flows": [flow], "messages": messages, "key_exprs": keys}


def access_control(route: Route, *, edge_name: str | Sequence[str]) -> dict[str, Any]:
    """Deny by default; the host's own nodes (TCP on loopback) may do anything among themselves. A replica's
    host lets only its prefixed keys cross, so the edge's merge sees every copy of a reply, the robot none.
    ``edge_name``: the common name of the edge routers' certificates (one per edge)."""
    rules = loopback_rules()
    rules += _link_rules("edge", receive=list(route.to_cloud + route.listed), send=list(route.to_edge + route.listed),
                         keys=replica_keys_prefix(route))
    edge_rules = [r["id"] for r in rules if not r["id"].startswith("local")]
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": [
            {"id": "host-nodes", "link_protocols": ["tcp"], "interfaces": ["lo"]},
            {"id": "edge", "link_protocols": ["tls"],
             "cert_common_names": [edge_name] if isinstance(edge_name, str) else list(edge_name)},
        ],
        "policies": [
            {"id": "host-nodes", "rules": ["local-in", "local-out"], "subjects": ["host-nodes"]},
            {"id": "edge", "rules": edge_rules, "subjects": ["edge"]},
        ],
    }


def namespace_key(robot: str) -> str:
    """rmw_zenoh's data keys of every topic in ``robot``'s namespace (``/<robot>/...``), any domain and type."""
    return f"*/{robot}/**"


def namespace_graph_keys(robot: str) -> list[str]:
    """The publisher and subscriber tokens of the topics in ``robot``'s namespace: the mangled topic is one chunk
    (``%<robot>%scan``), so ``$*`` within it never reaches another robot's (``%r1%`` is not ``%r10%``)."""
    return [f"{GRAPH_SPACE}/*/*/*/*/{kind}/*/*/*/%{robot}%$*/*/*/*" for kind in (PUBLISHER, SUBSCRIBER)]


def fleet_access_control(robots: Mapping[str, str], *, revoked: Collection[str] = ()) -> dict[str, Any]:
    """A fleet's cloud router: deny by default; the host's nodes (TCP on loopback) anything among themselves;
    each robot's edge router, known by its certificate's common name (``robots``: name -> common name), only the
    keys of its own namespace, both ways: its topics' data and subscriptions, their publisher/subscriber
    tokens. A shared request/reply node is reached through :mod:`fogiac.net.zenoh.fleet`, which carries each
    robot's requests and replies under that robot's namespace, so no shared plain key ever crosses a link.
    A ``revoked`` robot has no subject and no rule: its certificate gets nothing (deny is the default)."""
    rules = loopback_rules()
    subjects: list[dict[str, Any]] = [{"id": "host-nodes", "link_protocols": ["tcp"], "interfaces": ["lo"]}]
    policies: list[dict[str, Any]] = [{"id": "host-nodes", "rules": ["local-in", "local-out"],
                                       "subjects": ["host-nodes"]}]
    for robot in sorted(set(robots) - set(revoked)):
        mine = namespace_rules(f"robot-{robot}", robot)
        rules += mine
        subjects.append({"id": f"robot-{robot}", "link_protocols": ["tls"], "cert_common_names": [robots[robot]]})
        policies.append({"id": f"robot-{robot}", "rules": [r["id"] for r in mine], "subjects": [f"robot-{robot}"]})
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects,
            "policies": policies}


def namespace_rules(prefix: str, robot: str) -> list[dict[str, Any]]:
    """One link's rules for ``robot``'s namespace only, both ways: its topics' data and subscriptions, their
    publisher/subscriber tokens (the cloud router's rules for a robot, and the robot's edge router's for a cloud)."""
    data, tokens = [namespace_key(robot)], namespace_graph_keys(robot)
    return [_rule(f"{prefix}-data-in", "ingress", _DATA, data),
            _rule(f"{prefix}-data-out", "egress", _DATA, data),
            _rule(f"{prefix}-interest-in", "ingress", ["declare_subscriber"], data),
            _rule(f"{prefix}-interest-out", "egress", ["declare_subscriber"], data),
            _rule(f"{prefix}-graph-in", "ingress", ["liveliness_token"], tokens),
            _rule(f"{prefix}-graph-out", "egress", ["liveliness_token"], tokens)]


def edge_fleet_access_control(clouds: Sequence[str], robot: str) -> dict[str, Any]:
    """A fleet robot's edge router: deny by default; the robot's nodes (TCP on loopback) anything among themselves;
    each cloud router (``clouds``: their certificates' common names) only the robot's own namespace, the mirror of
    the cloud router's rules for it (:func:`fleet_access_control`). A cloud host that lost its rules still reaches
    nothing of the robot outside ``/<robot>/...``."""
    rules = loopback_rules()
    subjects: list[dict[str, Any]] = [{"id": "robot-nodes", "link_protocols": ["tcp"], "interfaces": ["lo"]}]
    policies: list[dict[str, Any]] = [{"id": "robot-nodes", "rules": ["local-in", "local-out"],
                                       "subjects": ["robot-nodes"]}]
    if clouds:
        mine = namespace_rules("cloud", robot)
        rules += mine
        subjects.append({"id": "cloud", "link_protocols": ["tls"], "cert_common_names": sorted(set(clouds))})
        policies.append({"id": "cloud", "rules": [r["id"] for r in mine], "subjects": ["cloud"]})
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects,
            "policies": policies}


def loopback_rules() -> list[dict[str, Any]]:
    """The rules ``local-in`` and ``local-out``: everything, both ways, data and graph; every router's policy gives
    them to the processes on its own machine (TCP on loopback) and to nothing else."""
    every = _DATA + ["declare_subscriber", "query", "reply", "declare_queryable"] + _GRAPH
    keys = ["**", f"{GRAPH_SPACE}/**"]  # ``**`` never matches a chunk starting with ``@``
    return [_rule("local-in", "ingress", every, keys), _rule("local-out", "egress", every, keys)]


def edge_access_control(clouds: Sequence[tuple[str, Route]]) -> dict[str, Any]:
    """The edge router's side: deny by default; the robot's nodes (TCP on loopback) may do anything among
    themselves; each cloud router, known by its certificate's common name, only its route's topics."""
    rules = loopback_rules()
    subjects: list[dict[str, Any]] = [{"id": "robot-nodes", "link_protocols": ["tcp"], "interfaces": ["lo"]}]
    policies: list[dict[str, Any]] = [{"id": "robot-nodes", "rules": ["local-in", "local-out"],
                                       "subjects": ["robot-nodes"]}]
    for n, (name, route) in enumerate(clouds):
        mine = _link_rules(f"cloud{n}", receive=list(route.to_edge + route.listed),
                           send=list(route.to_cloud + route.listed), keys=replica_keys_prefix(route))
        rules += mine
        subjects.append({"id": f"cloud{n}", "link_protocols": ["tls"], "cert_common_names": [name]})
        policies.append({"id": f"cloud{n}", "rules": [r["id"] for r in mine], "subjects": [f"cloud{n}"]})
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects,
            "policies": [p for p in policies if p["rules"]]}


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
        "connect": {"endpoints": list(connect), "timeout_ms": -1, "exit_on_failure": False,
                    "retry": dict(CONNECT_RETRY)},
        "scouting": {"multicast": {"enabled": False}, "gossip": dict(_GOSSIP)},
        "transport": {"link": {"tls": tls}},
        "adminspace": {"enabled": False},
    }


def cloud_router(route: Route, *, listen_host: str, tls: TlsFiles, edge_name: str | Sequence[str] = (),
                 local_port: int = LOCAL_PORT, robots: Mapping[str, str] | None = None,
                 revoked: Collection[str] = ()) -> dict[str, Any]:
    """The router on ``route.host``: mutual TLS for the edge on ``listen_host``, loopback for its nodes.

    One robot (``edge_name``): the route's topics (:func:`access_control`). A fleet (``robots``: each robot's
    name -> its edge router certificate's common name, ``revoked`` the names cut off): each robot only its own
    namespace (:func:`fleet_access_control`). Zenoh reads access control once, when the router opens; a
    deployed fleet's router (``--fleet-file``) therefore serves the TLS address itself and holds each robot's
    rules in a router of the robot's own (:mod:`fogiac.net.zenoh.gate`), so that robots come and go alone."""
    if robots is None and not edge_name:
        raise ValueError("a cloud router needs its edge's certificate name (edge_name) or a fleet (robots)")
    config = _base(listen=(f"tls/{listen_host}:{route.port}", f"tcp/127.0.0.1:{local_port}"), connect=(),
                   tls=_tls(tls, listen=True))
    config["access_control"] = (access_control(route, edge_name=edge_name) if robots is None
                                else fleet_access_control(robots, revoked=revoked))
    return config


def edge_router(cloud: Sequence[tuple[str, int]], *, tls: TlsFiles, policy: Sequence[tuple[str, Route]],
                local_port: int = LOCAL_PORT, robot: str | None = None) -> dict[str, Any]:
    """The robot's router: dials every cloud router, listens on loopback only (for the robot's nodes), and lets
    each cloud router (``policy``: its certificate's common name and its route) reach only its route's topics;
    a fleet's ``robot``: only that robot's namespace (:func:`edge_fleet_access_control`)."""
    config = _base(listen=(f"tcp/127.0.0.1:{local_port}",), connect=[f"tls/{host}:{port}" for host, port in cloud],
                   tls=_tls(tls, listen=False))
    config["access_control"] = (edge_access_control(policy) if robot is None
                                else edge_fleet_access_control([name for name, _ in policy], robot))
    return config

