"""Who may link to a cloud end of a fleet, and which topics each robot may touch.

A fleet's cloud end keeps an access file beside its certificates (``fleet.json``, written by
provisioning and rewritten by ``fogiac robot revoke``/``restore``)::

    {"robots": {"arm1": {"identity": "arm1.edge.lab.fogiac", "topics": ["/plan/request", "/plan/reply"]}},
     "revoked": ["arm3"],
     "shared": [{"node": "planner", "requests": ["/plan/request"], "replies": ["/plan/reply"],
                 "match": "header.stamp"}],
     "per_robot": [{"node": "slam", "in": ["/scan"], "out": ["/slam/count"]}]}

A robot may ask for (SUBSCRIBE) and send (OPEN) only the topics of its own namespace ``/<robot>/...`` and
the listed ones (the request/reply topics of the shared nodes that serve it; those named under ``shared``
only one way: it sends requests and hears replies); a certificate of no listed
robot, or of a revoked one, is not linked at all. The file is read again whenever it changes
(:class:`AccessWatch`), so robots are added and revoked with no process restarted. Without the file the
cloud end keeps the rules of a single edge (every identity linked, the topic policy alone decides).

``shared`` (optional) names each shared request/reply node's topics and the reply field that names a
request (the manifest's ``reply_match``; ``null``: its outputs carry no key): the cloud end sends each
reply only to the robot whose request it answers (:mod:`.replyroute`). A shared node's outputs not listed
there, or listed with no match, go to every robot that may subscribe them (the robots the node serves).

``per_robot`` (optional) names each per-robot node's listed topics (the manifest's ``in`` and ``out``, as the
node itself names them): its instance for robot arm1 uses them as ``/arm1/scan``..., so each robot's own
copies cross in their direction (:meth:`FleetAccess.crosses`) whatever the cloud end's topic policy says,
which keeps no robot's name (a robot added or removed changes the file, never the cloud end's command).
"""

from __future__ import annotations

import json
import logging
import os
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from fogiac.net.relay.graph import GraphState
from fogiac.net.relay.match import DEFAULT_MATCH

log = logging.getLogger(__name__)
ACCESS_FILE = "fleet.json"
POLL_S = 1.0  # how often the access file is checked for a change (revocation must bite within 10 s)


class AccessError(ValueError):
    """The access file is not what provisioning writes."""


@dataclass(frozen=True)
class Robot:
    name: str
    identity: str  # the common name in the robot's client certificate
    topics: frozenset[str] = frozenset()  # beyond its namespace: the shared nodes' request/reply topics

    def may_use(self, topic: str) -> bool:
        return topic.startswith(f"/{self.name}/") or topic in self.topics


def _topic_lists(body: dict[str, object], sides: tuple[str, ...], where: str, *,
                 required: bool) -> dict[str, frozenset[str]]:
    """Each of ``sides`` in an access file's entry: a list of absolute topic names, non-empty when ``required``
    (a shared pair's requests and replies), else possibly absent or empty (a per-robot node's in and out)."""
    topics: dict[str, frozenset[str]] = {}
    for side in sides:
        names = body.get(side) if required else body.get(side, [])
        if not isinstance(names, list) or (required and not names) or \
                not all(isinstance(t, str) and t.startswith("/") for t in names):
            said = "a non-empty list of absolute topic names" if required else "a list of absolute topic names"
            raise AccessError(f"{where} ({body['node']}): '{side}' must be {said}")
        topics[side] = frozenset(names)
    return topics


@dataclass(frozen=True)
class SharedPair:
    """A shared node's request and reply topics, and the reply field that names its request (None: no key)."""

    node: str
    requests: frozenset[str]
    replies: frozenset[str]
    match: str | None = DEFAULT_MATCH

    def to_json(self) -> dict[str, object]:
        return {"node": self.node, "requests": sorted(self.requests), "replies": sorted(self.replies),
                "match": self.match}

    @classmethod
    def from_json(cls, body: object, where: str) -> SharedPair:
        if not isinstance(body, dict) or not isinstance(body.get("node"), str):
            raise AccessError(f"{where} needs a 'node' string")
        topics = _topic_lists(body, ("requests", "replies"), where, required=True)
        match = body.get("match", DEFAULT_MATCH)
        if match is not None and (not isinstance(match, str) or not [p for p in match.split(".") if p]):
            raise AccessError(f"{where} ({body['node']}): 'match' must be a dotted field path or null")
        return cls(body["node"], topics["requests"], topics["replies"], match)


@dataclass(frozen=True)
class PerRobot:
    """A per-robot node's listed topics as the node names them (``/scan``); each robot's instance uses them in
    that robot's namespace (``/arm1/scan``). ``inputs`` reach the node (the robot sends them), ``outputs``
    come from it (the robot hears them)."""

    node: str
    inputs: frozenset[str] = frozenset()
    outputs: frozenset[str] = frozenset()

    def to_json(self) -> dict[str, object]:
        return {"node": self.node, "in": sorted(self.inputs), "out": sorted(self.outputs)}

    @classmethod
    def from_json(cls, body: object, where: str) -> PerRobot:
        if not isinstance(body, dict) or not isinstance(body.get("node"), str):
            raise AccessError(f"{where} needs a 'node' string")
        topics = _topic_lists(body, ("in", "out"), where, required=False)
        return cls(body["node"], topics["in"], topics["out"])


@dataclass(frozen=True)
class FleetAccess:
    """The parsed access file: robots by certificate identity, the revoked robots' names, and the shared
    request/reply nodes whose replies are routed to the robot that asked."""

    robots: Mapping[str, Robot] = field(default_factory=dict)
    revoked: frozenset[str] = frozenset()
    shared: tuple[SharedPair, ...] = ()
    per_robot: tuple[PerRobot, ...] = ()

    def robot(self, identity: str) -> Robot | None:
        """The robot this identity may link as; None when it is unknown or revoked."""
        robot = self.robots.get(identity)
        return None if robot is None or robot.name in self.revoked else robot

    def allows(self, identity: str, topic: str, direction: str | None = None) -> bool:
        """Whether the robot may use ``topic``; with a ``direction`` (``out``: it sends, ``in``: it hears), a shared
        node's topics only the way a client uses them: it sends requests and hears replies, so it never reads
        its neighbours' requests nor poses as the node."""
        robot = self.robot(identity)
        if robot is None or not robot.may_use(topic):
            return False
        if direction == "in":
            return not any(topic in pair.requests for pair in self.shared)
        if direction == "out":
            return not any(topic in pair.replies for pair in self.shared)
        return True

    def crosses(self, identity: str, topic: str, direction: str) -> bool:
        """Whether ``topic`` is one of this robot's own per-robot instances' topics in ``direction`` (``out``: the
        robot sends it to the node, ``in``: it hears the node's): ``/arm1/scan`` for arm1 only, never for arm2."""
        robot = self.robot(identity)
        if robot is None or not topic.startswith(f"/{robot.name}/"):
            return False
        bare = topic[len(robot.name) + 1:]
        return any(bare in (node.inputs if direction == "out" else node.outputs) for node in self.per_robot)

    def visible(self, identity: str, graph: GraphState) -> GraphState:
        """The part of the cloud's graph this robot may use: other robots' topic names are not its business."""
        robot = self.robot(identity)

        def keep(side: Mapping[str, frozenset[str]]) -> dict[str, frozenset[str]]:
            return {t: n for t, n in side.items() if robot is not None and robot.may_use(t)}

        types = {t: ty for t, ty in graph.types.items() if robot is not None and robot.may_use(t)}
        return GraphState(keep(graph.publishers), keep(graph.subscribers), types)

    def to_json(self) -> dict[str, object]:
        body: dict[str, object] = {"robots": {r.name: {"identity": r.identity, "topics": sorted(r.topics)}
                                              for r in sorted(self.robots.values(), key=lambda r: r.name)},
                                   "revoked": sorted(self.revoked)}
        if self.shared:
            body["shared"] = [pair.to_json() for pair in self.shared]
        if self.per_robot:
            body["per_robot"] = [node.to_json() for node in self.per_robot]
        return body

    @classmethod
    def from_json(cls, body: object) -> FleetAccess:
        if not isinstance(body, dict) or not isinstance(body.get("robots"), dict):
            raise AccessError("needs a 'robots' object")
        robots: dict[str, Robot] = {}
        for name, entry in body["robots"].items():
            if not isinstance(entry, dict) or not isinstance(entry.get("identity"), str):
                raise AccessError(f"robot {name!r} needs an 'identity' string")
            topics = entry.get("topics", [])
            if not isinstance(topics, list) or not all(isinstance(t, str) and t.startswith("/") for t in topics):
                raise AccessError(f"robot {name!r}: 'topics' must be a list of absolute topic names")
            robots[entry["identity"]] = Robot(str(name), entry["identity"], frozenset(topics))
        revoked = body.get("revoked", [])
        if not isinstance(revoked, list) or not all(isinstance(n, str) for n in revoked):
            raise AccessError("'revoked' must be a list of robot names")
        shared = body.get("shared", [])
        if not isinstance(shared, list):
            raise AccessError("'shared' must be a list of shared request/reply nodes")
        pairs = tuple(SharedPair.from_json(entry, f"shared[{i}]") for i, entry in enumerate(shared))
        seen: dict[str, str] = {}
        for pair in pairs:
            for topic in sorted(pair.requests | pair.replies):
                if topic in seen:
                    raise AccessError(f"topic {topic} belongs to two shared nodes' pairs ({seen[topic]}, {pair.node})")
                seen[topic] = pair.node
        per_robot = body.get("per_robot", [])
        if not isinstance(per_robot, list):
            raise AccessError("'per_robot' must be a list of per-robot nodes")
        nodes = tuple(PerRobot.from_json(entry, f"per_robot[{i}]") for i, entry in enumerate(per_robot))
        return cls(robots, frozenset(revoked), pairs, nodes)


def write_access(path: Path, access: FleetAccess) -> None:
    """Replace the access file at once (a reader never sees half of it)."""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(access.to_json(), indent=2, sort_keys=True) + "\n")
    os.chmod(tmp, 0o600)
    os.replace(tmp, path)


def read_access(path: Path) -> FleetAccess | None:
    """The access file's rules; None when there is no file (a single edge's cloud end); AccessError if bad."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        return None
    except OSError as err:
        raise AccessError(f"cannot read {path}: {err}") from None
    try:
        return FleetAccess.from_json(json.loads(text))
    except (json.JSONDecodeError, AccessError) as err:
        raise AccessError(f"{path}: {err}") from None


_DENY_ALL = FleetAccess()  # a fleet file that never parsed: no robot is linked (fail closed)


class AccessWatch:
    """The access file's current rules, re-read when its stat changes (or :meth:`reload` on SIGHUP).

    A file that stops parsing keeps the last good rules (logged); one that never parsed links no robot.
    ``on_change`` is called with the new rules after each change, so the cloud end closes the links that
    lost their access."""

    def __init__(self, path: Path, on_change: Callable[[FleetAccess | None], None]) -> None:
        self.path, self._on_change = path, on_change
        self._stamp: tuple[int, int, int] | None = None
        self._lock = threading.Lock()
        self.rules: FleetAccess | None = None
        self.reload()

    def _stat(self) -> tuple[int, int, int] | None:
        try:
            st = self.path.stat()
        except OSError:
            return None
        return st.st_mtime_ns, st.st_size, st.st_ino

    def reload(self) -> None:
        with self._lock:
            self._stamp = self._stat()
            try:
                rules = read_access(self.path)
            except AccessError as err:
                log.error("fleet access file: %s; keeping the previous rules", err)
                rules = self.rules if self.rules is not None else _DENY_ALL
            self.rules = rules
        if rules is not None:
            log.info("fleet access: %d robots, %d revoked", len(rules.robots), len(rules.revoked))
        self._on_change(rules)

    def run(self, stopping: threading.Event) -> None:
        while not stopping.wait(POLL_S):
            if self._stat() != self._stamp:
                self.reload()
