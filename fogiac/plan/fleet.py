"""What a fleet plan says about its robots and whom each node serves, as plain rows for tables and JSON.

Pure, like :mod:`fogiac.plan.cost`: everything comes from the compiled Plan. A robot is what adding or
removing it changes, and nothing else: its certificate, its access rules (its namespace ``/<robot>/...``
and the topics of the nodes that serve it) and its edge links, one to each host; no host is part of it,
so a reviewer sees that a robot comes and goes without a machine touched.

A node's hourly cost is its host's, split evenly between the processes on the host (a per-robot node's
instances each count as one); each robot a shared node serves bears an equal share of it, and each robot
bears its own instance of a per-robot node. A robot's cost is
the sum of its shares plus what the target bills per robot (a cost line marked ``per_robot``: on aws its
Client VPN connection): the robots' costs add up to the hosts' and those lines. An unknown price makes every
share it enters unknown (None), never $0.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from fogiac.certs import edge_identity
from fogiac.net import middleware
from fogiac.plan.model import NodeSpec, Plan, Route


def instances(plan: Plan, node: NodeSpec) -> int:
    """How many copies of ``node`` run: one per robot for ``serve: per_robot``, else one every robot shares."""
    return len(plan.robots_of(node)) if node.per_robot else 1


def node_usd_per_hour(plan: Plan, node: NodeSpec) -> float | None:
    """The node's part of its host's hour (None: the host's price is unknown): the host's hour split evenly
    between the processes it runs, a per-robot node counting one per instance, so three robots' SLAM on a
    host beside a shared planner bear three quarters of it."""
    host = plan.host(node.host)
    if host.usd_per_hour is None:
        return None
    running = sum(instances(plan, plan.node(name)) for name in host.nodes)
    return host.usd_per_hour * instances(plan, node) / max(1, running)


def share(plan: Plan, node: NodeSpec) -> float | None:
    """What each robot ``node`` serves bears of its hour."""
    hourly = node_usd_per_hour(plan, node)
    return None if hourly is None else round(hourly / len(plan.robots_of(node)), 6)


def node_row(plan: Plan, node: NodeSpec) -> dict[str, Any]:
    """A fleet node's row additions: whom it serves, its instances and each robot's share of its hour."""
    return {"serves": list(plan.robots_of(node)), "serve": "per_robot" if node.per_robot else
            "all" if not node.serves else "list", "instances": instances(plan, node),
            "usd_per_hour_per_robot": share(plan, node)}


def access(plan: Plan, robot: str) -> list[str]:
    """The topics a robot may cross: its namespace, and the topics of the shared nodes that serve it but for
    those in another robot's namespace (that robot's alone, as every cloud end's access file has it)."""
    others = tuple(f"/{edge.name}/" for edge in plan.edges if edge.name != robot)
    shared = {topic for node in plan.nodes if robot in plan.robots_of(node) and not node.per_robot
              for topic in (*node.topics_in, *node.topics_out) if not topic.startswith(others)}
    return [f"/{robot}/..."] + sorted(shared)


def robot_cost(plan: Plan, robot: str) -> float | None:
    """The robot's share of the hosts' hour: the sum of its nodes' shares, and one of each line the target bills
    per robot (None when one is unknown)."""
    shares = [share(plan, node) for node in plan.nodes if robot in plan.robots_of(node)]
    shares += [line.usd_per_hour for line in plan.cost if line.per_robot]
    if any(each is None for each in shares):
        return None
    return round(sum(each for each in shares if each is not None), 6)


def robots(plan: Plan) -> list[dict[str, Any]] | None:
    """Each robot of a fleet with what it brings: its certificate, access rules, edge links, its own instances of
    the per-robot nodes and its cost share;
    None for a plan of one robot (``edge:``), whose document stays as it was."""
    if not plan.fleet:
        return None
    # the middleware names its robots' certificates where it has its own (Zenoh's edge routers'), else the relay's
    named = getattr(middleware.get(plan.middleware), "robot_certificate", None)
    rows: list[dict[str, Any]] = []
    for edge in plan.edges:
        row = {"name": edge.name, "entry": edge.entry,
               "certificate": named(plan.stack, edge.name) if named is not None and edge.named is not None
               else edge_identity(plan.stack, edge.named),
               "access": access(plan, edge.name), "edge_links": [route.host for route in plan.routes],
               "nodes": [node.name for node in plan.nodes if edge.name in plan.robots_of(node)],
               "usd_per_hour": robot_cost(plan, edge.name)}
        own = [f"{node.name}@{edge.name} on {node.host}" for node in plan.nodes
               if node.per_robot and edge.name in plan.robots_of(node)]
        if own:  # its per-robot nodes' instances, which come and go with it (absent: the rows as before)
            row["instances"] = own
        rows.append(row)
    return rows


def rows(plan: Plan) -> tuple[list[dict[str, Any]], list[dict[str, Any]] | None]:
    """What the plan document shows of a fleet, asked in one call: each node's row additions (:func:`node_row`,
    in the plan's order; ``{}`` each for a plan of one robot) and the robots (:func:`robots`)."""
    return [node_row(plan, node) if plan.fleet else {} for node in plan.nodes], robots(plan)


def in_namespace(robot: str, topic: str) -> str:
    """A per-robot node's topic as its instance for ``robot`` uses it: ``/scan`` is arm1's ``/arm1/scan``."""
    return f"/{robot}{topic}"


def _per_robot_only(plan: Plan, host: str) -> tuple[frozenset[str], frozenset[str]]:
    """(in, out): the topics on ``host`` only its per-robot nodes list, which no shared node there uses bare."""
    mine = [node for node in plan.nodes if node.host == host]
    shared_in = {t for node in mine if not node.per_robot for t in node.topics_in}
    shared_out = {t for node in mine if not node.per_robot for t in node.topics_out}
    return (frozenset(t for node in mine if node.per_robot for t in node.topics_in) - shared_in,
            frozenset(t for node in mine if node.per_robot for t in node.topics_out) - shared_out)


def shared_route(plan: Plan, route: Route) -> Route:
    """``route`` without the bare topics of the host's per-robot nodes: what crosses for no robot in
    particular (the cloud end's policy, which a robot added or removed must leave unchanged)."""
    only_in, only_out = _per_robot_only(plan, route.host)
    if not only_in and not only_out:
        return route
    return dataclasses.replace(route, to_cloud=tuple(t for t in route.to_cloud if t not in only_in),
                               to_edge=tuple(t for t in route.to_edge if t not in only_out))


def robot_route(plan: Plan, route: Route, robot: str) -> Route:
    """What crosses between ``robot`` and ``route``'s host: the shared topics, and its own per-robot instances'
    topics in its namespace (``/arm1/scan``), never another robot's instance's."""
    bare = shared_route(plan, route)
    mine = [node for node in plan.nodes if node.host == route.host and node.per_robot and robot in plan.robots_of(node)]
    if not mine:
        return bare
    to_cloud = {in_namespace(robot, t) for node in mine for t in node.topics_in}
    to_edge = {in_namespace(robot, t) for node in mine for t in node.topics_out}
    return dataclasses.replace(bare, to_cloud=tuple(sorted({*bare.to_cloud, *to_cloud})),
                               to_edge=tuple(sorted({*bare.to_edge, *to_edge})))
