"""Which topics cross the relay, decided from both masters' graphs. Pure.

Each end reports its master's ``getSystemState`` with the relay's own registrations left out
(that is what keeps a relayed topic from bouncing back). The edge then applies
:func:`select_routes`: in ``auto`` mode a topic crosses whenever it has a publisher on one
side and a subscriber on the other, and stops crossing when either goes away.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

Direction = Literal["out", "in"]  # out: edge -> cloud; in: cloud -> edge
DEFAULT_IGNORE = ("/rosout", "/rosout_agg", "/fogros/")


@dataclass(frozen=True)
class GraphState:
    """Topic -> registered nodes, for publishers and subscribers of one master; ``types``: the
    published topics' message types, where the master knows them (the cloud reports them)."""

    publishers: Mapping[str, frozenset[str]] = field(default_factory=dict)
    subscribers: Mapping[str, frozenset[str]] = field(default_factory=dict)
    types: Mapping[str, str] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        body: dict[str, Any] = {
            "publishers": {t: sorted(n) for t, n in sorted(self.publishers.items())},
            "subscribers": {t: sorted(n) for t, n in sorted(self.subscribers.items())},
        }
        if self.types:
            body["types"] = dict(sorted(self.types.items()))
        return body

    @classmethod
    def from_json(cls, body: Mapping[str, Any]) -> GraphState:
        def side(key: str) -> dict[str, frozenset[str]]:
            raw = body.get(key, {})
            if not isinstance(raw, dict):
                raise ValueError(f"{key} must be an object")
            return {str(t): frozenset(map(str, nodes)) for t, nodes in raw.items()}

        types = body.get("types", {})
        if not isinstance(types, dict):
            raise ValueError("types must be an object")
        return cls(side("publishers"), side("subscribers"), {str(t): str(ty) for t, ty in types.items()})


def from_system_state(state: Any, *, exclude: Iterable[str], types: Mapping[str, str] | None = None) -> GraphState:
    """A GraphState from the master's ``[publishers, subscribers, services]`` answer (and, with
    ``types``, its ``getTopicTypes``: kept for the published topics only)."""
    skip = set(exclude)

    def side(entries: Any) -> dict[str, frozenset[str]]:
        out: dict[str, frozenset[str]] = {}
        for topic, nodes in entries:
            kept = frozenset(n for n in nodes if n not in skip)
            if kept:
                out[topic] = kept
        return out

    publishers = side(state[0])
    known = {t: ty for t, ty in (types or {}).items() if t in publishers and ty != "*"}
    return GraphState(publishers, side(state[1]), known)


@dataclass(frozen=True)
class TopicPolicy:
    """What the edge was told to relay.

    ``out_topics``/``in_topics`` always cross in their direction; ``topics`` cross in whichever
    direction has a publisher; ``auto`` adds every topic with a publisher on one side and a
    subscriber on the other. Topics starting with an ``ignore`` prefix never cross on their own.
    """

    auto: bool = False
    topics: tuple[str, ...] = ()
    out_topics: tuple[str, ...] = ()
    in_topics: tuple[str, ...] = ()
    ignore: tuple[str, ...] = DEFAULT_IGNORE


@dataclass(frozen=True, order=True)
class Route:
    topic: str
    direction: Direction


def _ignored(topic: str, prefixes: tuple[str, ...]) -> bool:
    return any(topic == p or (p.endswith("/") and topic.startswith(p)) for p in prefixes)


def may_cross(topic: str, direction: Direction, policy: TopicPolicy, local: GraphState) -> bool:
    """May the far end start ``topic`` in ``direction``? Asked by the cloud end of its own graph
    (``local``): listed topics always, and in auto mode only what its nodes publish ("in") or
    subscribe to ("out")."""
    if topic in policy.topics or topic in (policy.out_topics if direction == "out" else policy.in_topics):
        return True
    if not policy.auto or _ignored(topic, policy.ignore):
        return False
    side = local.subscribers if direction == "out" else local.publishers
    return bool(side.get(topic))


def select_routes(edge: GraphState, cloud: GraphState, policy: TopicPolicy) -> frozenset[Route]:
    routes = {Route(t, "out") for t in policy.out_topics} | {Route(t, "in") for t in policy.in_topics}
    for topic in policy.topics:
        if edge.publishers.get(topic):
            routes.add(Route(topic, "out"))
        if cloud.publishers.get(topic):
            routes.add(Route(topic, "in"))
    if policy.auto:
        for topic in edge.publishers.keys() & cloud.subscribers.keys():
            if not _ignored(topic, policy.ignore):
                routes.add(Route(topic, "out"))
        for topic in cloud.publishers.keys() & edge.subscribers.keys():
            if not _ignored(topic, policy.ignore):
                routes.add(Route(topic, "in"))
    return frozenset(routes)


def type_hints(cloud: GraphState, policy: TopicPolicy, *, routed: Iterable[str] = ()) -> dict[str, str]:
    """In ``auto`` mode, the type of each topic the cloud publishes that could cross to the edge but does
    not yet (no edge subscriber): the edge master must know it, since ``rostopic echo`` asks the master
    for a topic's type and subscribes only once it has one (a subscriber with ``*`` never comes)."""
    if not policy.auto:
        return {}
    skip = set(routed)
    return {t: ty for t, ty in cloud.types.items()
            if cloud.publishers.get(t) and t not in skip and not _ignored(t, policy.ignore)}
