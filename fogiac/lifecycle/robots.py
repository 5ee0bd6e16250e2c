"""A fleet's robots in ``fogiac status``: one row each, from the stack record's edges and each robot's edge stats.

The record's edges list (:func:`fogiac.lifecycle.edge.record_edge`) says which robots the last ``up`` linked,
each with its ROS master and its links (host -> HOST:PORT); the robot's edge end rewrites its stats file every
second, read here through the middleware's own reader (:meth:`fogiac.net.middleware.Deployment.edge_links`), so
this module knows no middleware's file names. A stack of one robot (``edge:``, its one edge named after the
stack) has no robot rows: its status reads as it always did.

What a row sums up, over the robot's links: how many are up (and the best round trip), the topics that
carried messages, the median one-way latency of its topics and the worst 99th percentile, what the robot sent
(manifest direction ``in``: robot to node), the requests served (``out``: messages the nodes sent back to this
robot; and the shared request/reply nodes' replies its cloud ends routed to it, as they counted them and told
its edge end, with those lost because its link was down: ``routed``), and the drops and topics its cloud ends
refused it; and why a cloud end refused the robot's link itself, as its edge end heard it (``refused:
revoked``), which the record may not know (revoked from another machine).
"""

from __future__ import annotations

import dataclasses
import math
import statistics
from collections.abc import Mapping, Sequence
from typing import Any

from fogiac.lifecycle.edge import edge_dir
from fogiac.net import middleware
from fogiac.plan.model import EdgeSpec, Plan
from fogiac.state import StackState
from fogiac.tables import printable, table


def recorded_robots(stack: str, edges: object) -> list[Mapping[str, Any]]:
    """The record's edges that are robots of a fleet: every one but the edge named after the stack."""
    if not isinstance(edges, list):
        return []
    return [e for e in edges if isinstance(e, Mapping) and isinstance(e.get("name"), str) and e["name"] != stack]


def robot_count(stack: str) -> int:
    """How many robots the stack's record links (0: a stack of one robot, or none recorded)."""
    return len(recorded_robots(stack, StackState(stack).get(StackState.EDGES)))


def _links(plan: Plan, robot: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The robot's links with its edge end's figures, read by the middleware from the robot's stats files."""
    connect = robot.get("relays")
    if not isinstance(connect, Mapping) or not connect:
        return []
    edge = EdgeSpec(name=str(robot["name"]), entry=str(robot.get("edge_master", "")))
    alone = dataclasses.replace(plan, edges=(edge,))
    return middleware.deployment(plan.middleware).edge_links(
        alone, folder=edge_dir(plan, create=False), connect={str(h): str(a) for h, a in connect.items()})


def _number(value: Any) -> float | None:
    """A figure from a stats file, or None where it holds anything else (text, NaN, infinity, a boolean)."""
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
        return None
    return float(value)


def _up(link: Mapping[str, Any]) -> bool:
    return link.get("connected") is True  # "yes" or 1 in a file fogiac did not write is not a link


def _routed(links: Sequence[Mapping[str, Any]]) -> dict[str, int] | None:
    """The shared nodes' replies the robot's cloud ends routed to it (``served``) and, of those, the ones its link
    was gone for (``undelivered``), summed over the links whose edge end heard the counts; None: none did (one
    robot's stack, no shared request/reply node, or an edge end from before the counts)."""
    heard = [r for link in links if isinstance(r := link.get("routed"), Mapping)]
    if not heard:
        return None
    return {key: sum(int(_number(r.get(key)) or 0) for r in heard) for key in ("served", "undelivered")}


def summary(name: str, robot: Mapping[str, Any], links: Sequence[Mapping[str, Any]],
            running: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """One robot's row from its links' figures and its running edge processes."""
    topics = [t for link in links for t in link.get("topics", []) if isinstance(t, Mapping)]
    latencies = [v for t in topics if (v := _number(t.get("latency_ms"))) is not None]
    p99 = [v for t in topics if (v := _number(t.get("latency_p99_ms"))) is not None]
    rtts = [v for link in links if _up(link) and (v := _number(link.get("rtt_ms"))) is not None]

    def total(key: str, direction: str | None = None) -> int:
        return sum(int(_number(t.get(key)) or 0) for t in topics
                   if direction is None or t.get("direction") == direction)

    return {"robot": name, "edge_master": robot.get("edge_master"), "revoked": bool(robot.get("revoked")),
            "links": [{"host": link.get("host"), "connected": _up(link), "rtt_ms": _number(link.get("rtt_ms"))}
                      for link in links],
            "links_up": sum(1 for link in links if _up(link)), "rtt_ms": min(rtts) if rtts else None,
            "topics": sorted({str(t.get("topic")) for t in topics if (_number(t.get("msgs")) or 0) > 0}),
            "latency_ms": round(statistics.median(latencies), 3) if latencies else None,
            "latency_p99_ms": max(p99) if p99 else None,
            "sent": total("msgs", "in"), "served": total("msgs", "out"), "drops": total("drops"),
            "refused": sum(int(_number(link.get("refused")) or 0) for link in links),
            "link_refused": sorted({v for link in links if isinstance(v := link.get("link_refused"), str)}),
            "routed": _routed(links),
            "processes": [{"name": p.get("name"), "pid": p.get("pid")} for p in running]}


def robot_status(plan: Plan, running: Sequence[Mapping[str, Any]] = ()) -> list[dict[str, Any]]:
    """One row per robot the record links, each from its own stats files; [] for a stack of one robot.
    ``running``: the stack's edge processes that run (a robot's carry ``@<robot>`` after their name). A robot
    is revoked where the record's revoked list (``fogiac robot revoke``) names it: its edge entry says nothing
    of it, and its link merely down would hide why."""
    state = StackState(plan.stack)
    robots = recorded_robots(plan.stack, state.get(StackState.EDGES))
    listed = state.get(StackState.REVOKED)
    revoked = {str(name) for name in listed} if isinstance(listed, list) else set()
    return [summary(str(r["name"]), {**r, "revoked": True} if r["name"] in revoked else r, _links(plan, r),
                    [p for p in running if str(p.get("name", "")).endswith(f"@{r['name']}")]) for r in robots]


def robots_table(rows: Sequence[Mapping[str, Any]]) -> Any:
    """The rows as ``fogiac status`` prints them (every value printable: a record's text drives no terminal)."""
    shown = table(f"robots ({len(rows)}; served: replies the nodes sent the robot)", "robot", "ROS master", "link",
                  "topics", "latency ms (median / p99)", "sent", "served", "drops", "refused", "edge process")

    def ms(value: Any) -> str:
        return "-" if value is None else f"{value:.2f}"

    def served(r: Mapping[str, Any]) -> str:
        routed = r.get("routed")
        if not routed:
            return str(r["served"])
        return f"{r['served']} (routed {routed['served']}" + (
            f", lost {routed['undelivered']})" if routed["undelivered"] else ")")

    for r in rows:
        links = r["links"]
        if r["revoked"]:
            link = "revoked"
        elif not links:
            link = "no link recorded"
        else:
            state = "up" if r["links_up"] == len(links) else "partly up" if r["links_up"] else "down"
            link = f"{state} {r['links_up']}/{len(links)}" + (
                f" ({r['rtt_ms']:.2f} ms)" if r["rtt_ms"] is not None else "") + (
                f" (refused: {', '.join(r['link_refused'])})" if r.get("link_refused") else "")
        pids = ", ".join(str(p["pid"]) for p in r["processes"]) or "not running"
        shown.add_row(*map(printable, (r["robot"], str(r["edge_master"] or "-"), link,
                                       ", ".join(r["topics"]) or "-",
                                       f"{ms(r['latency_ms'])} / {ms(r['latency_p99_ms'])}", str(r["sent"]),
                                       served(r), str(r["drops"]), str(r["refused"]), pids)))
    return shown
