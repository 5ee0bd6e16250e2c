"""What changes between two plan documents: per resource, and in what a reviewer reads around them.

Pure: two documents in (:mod:`fogiac.plan.document`; the "before" one may be None, when nothing
was applied, or of format version 1), a :class:`PlanDiff` out. No engine, no state, no
credentials, so the same code answers ``plan`` against the applied document and ``plan
--against`` another manifest.

Resources are matched by (stack, type, name). A changed input replaces the resource when the
provider's rules say so (plug-in group ``fogiac.replacements``, e.g. ``fogiac.targets.aws.replace``);
a replaced resource gets new ids, so every resource whose inputs name it (``<name.id>``
placeholders) sees that input change too, and may be replaced in turn: a new VPC CIDR replaces
everything in the VPC. Secrets are compared and shown as the documents hold them, ``[secret]``.
"""

from __future__ import annotations

import dataclasses
import ipaddress
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

from fogiac import registry
from fogiac.plan.document import shown_env
from fogiac.plan.drift import Drift

Action = Literal["create", "update", "replace", "delete", "no-op"]
KNOWN_AFTER_APPLY = "(known after apply)"
SETTINGS = ("target", "region", "zone", "mode", "edge_master", "autostop", "relay", "registries")
GROUP = "fogiac.replacements"  # package -> forces_replacement(type_, path), the provider's ForceNew rules
_PLACEHOLDER = re.compile(r"<([^<>]+)\.[A-Za-z]+>")


@dataclass(frozen=True)
class InputChange:
    path: str  # dotted input path, e.g. rootBlockDevice.volumeSize
    before: Any
    after: Any
    forces_replacement: bool


@dataclass(frozen=True)
class ResourceChange:
    stack: str
    type: str
    name: str
    action: Action
    changes: tuple[InputChange, ...] = ()
    because: tuple[str, ...] = ()  # why a replacement: forcing inputs, replaced dependencies
    inputs: Mapping[str, Any] = field(default_factory=dict)  # after (before, for a delete)


@dataclass(frozen=True)
class RowChange:
    """A keyed row (host, node) present on both sides with some fields changed."""

    key: str
    fields: tuple[tuple[str, Any, Any], ...]  # (field, before, after)


@dataclass(frozen=True)
class Section:
    added: tuple[Mapping[str, Any], ...] = ()
    removed: tuple[Mapping[str, Any], ...] = ()
    changed: tuple[RowChange, ...] = ()

    @property
    def empty(self) -> bool:
        return not (self.added or self.removed or self.changed)


@dataclass(frozen=True)
class PlanDiff:
    against: str  # "nothing", "applied" or "manifest"
    resources: tuple[ResourceChange, ...]  # every resource of either side, after's order, deletes last
    hosts: Section
    nodes: Section
    topics: Section
    security_rules: Section
    settings: tuple[tuple[str, Any, Any], ...]
    cost_before: float  # on-demand throughout
    cost_after: float
    exposure: tuple[str, ...]  # changes that open something up, each one line
    drift: tuple[Drift, ...] = ()  # against the applied document: what the last refresh found changed outside fogiac
    refreshed_at: str = ""  # when that refresh ran
    spot_before: float | None = None  # the hour with spot hosts at the spot estimate; None: no spot host that side
    spot_after: float | None = None
    spot_as_of: str = ""  # the spot estimates' date (the catalogue's Spot Instance Advisor snapshot)
    pushed: Section = Section()  # workspaces, env scripts, requirements, build contexts: path and content digest
    cost_risk: tuple[str, ...] = ()  # changes that let the stack cost more while nobody uses it (autostop weakened)
    autostop: Mapping[str, Any] | None = None  # the after side's autostop (None: off)
    autostop_known: bool = False  # the after document says its autostop (format 2 from this fogiac on)
    unknown_before: int = 0  # cost lines each side whose price is unknown: the hour is then "at least"
    unknown_after: int = 0
    # A fleet's robots (either side lists ``robots``): each added or removed one is its certificate, access rules
    # and edge links, never a host; a changed one, what it may cross or where it links.
    robots: Section = Section()
    fleet: bool = False

    def count(self, action: Action) -> int:
        return sum(1 for r in self.resources if r.action == action)

    @property
    def changed_resources(self) -> tuple[ResourceChange, ...]:
        return tuple(r for r in self.resources if r.action != "no-op")

    @property
    def empty(self) -> bool:
        sections = (self.hosts, self.nodes, self.topics, self.security_rules, self.pushed, self.robots)
        return (not self.changed_resources and all(s.empty for s in sections) and not self.settings
                and self.cost_before == self.cost_after and self.spot_before == self.spot_after and not self.drift)

    @property
    def has_spot(self) -> bool:
        return self.spot_before is not None or self.spot_after is not None

    @property
    def expected_before(self) -> float:
        """The hour as it is expected to cost: spot hosts at their estimate, everything else on-demand."""
        return self.cost_before if self.spot_before is None else self.spot_before

    @property
    def expected_after(self) -> float:
        return self.cost_after if self.spot_after is None else self.spot_after

    def counts(self) -> tuple[int, int, int]:
        """(to add, to change, to destroy): the resources, a replacement once to add and once to destroy.

        A target that declares no resources on either side (local sandboxes, machines that exist) deploys
        hosts, not resources: its hosts are counted instead, or a changed machine on ``local`` showed
        ``~ planner machine: ...`` above "Plan: 0 to add, 0 to change, 0 to destroy."
        """
        if not self.resources:
            return len(self.hosts.added), len(self.hosts.changed), len(self.hosts.removed)
        replaced = self.count("replace")
        return self.count("create") + replaced, self.count("update"), self.count("delete") + replaced

    def summary(self) -> str:
        """Terraform's line (:meth:`counts`); then a fleet's robots, and the drift, if any."""
        add, change, destroy = self.counts()
        line = f"Plan: {add} to add, {change} to change, {destroy} to destroy."
        if not self.robots.empty:
            line += (f" Robots: {len(self.robots.added)} to add, {len(self.robots.changed)} to change, "
                     f"{len(self.robots.removed)} to remove.")
        if self.drift:
            counts = [f"{n} {status}" for status in ("changed", "deleted", "added")
                      if (n := sum(1 for d in self.drift if d.status == status))]
            line += f" Drift: {', '.join(counts)} outside fogiac."
        return line

    def to_dict(self) -> dict[str, Any]:
        def section(s: Section) -> dict[str, Any]:
            return {"added": [dict(r) for r in s.added], "removed": [dict(r) for r in s.removed],
                    "changed": [{"key": c.key, "before": {f: b for f, b, _ in c.fields},
                                 "after": {f: a for f, _, a in c.fields}} for c in s.changed]}

        return {
            "against": self.against, "empty": self.empty, "summary": self.summary(),
            **dict(zip(("add", "change", "destroy"), self.counts(), strict=True)),
            "hosts": section(self.hosts), "nodes": section(self.nodes), "topics": section(self.topics),
            "security_rules": section(self.security_rules), "pushed": section(self.pushed),
            "settings": [{"name": k, "before": b, "after": a} for k, b, a in self.settings],
            "cost": {"hourly_usd_before": self.cost_before, "hourly_usd_after": self.cost_after,
                     **({"spot_hourly_usd_before": self.spot_before, "spot_hourly_usd_after": self.spot_after,
                         "spot_as_of": self.spot_as_of} if self.has_spot else {})},
            "exposure": list(self.exposure), "cost_risk": list(self.cost_risk),
            "drift": [d.to_dict() for d in self.drift], "refreshed_at": self.refreshed_at or None,
            **({"robots": section(self.robots)} if self.fleet else {}),  # a one-robot plan's changes as before
        }


def leaves(value: Any, prefix: str = "") -> Iterator[tuple[str, Any]]:
    """Nested mappings flattened to dotted paths; lists and scalars are leaves."""
    if isinstance(value, Mapping) and value:
        for key in sorted(value):
            yield from leaves(value[key], f"{prefix}.{key}" if prefix else str(key))
    else:
        yield prefix, value


def _names(value: Any) -> set[str]:
    """The resources an input refers to through ``<name.attr>`` placeholders."""
    return {m.group(1) for _, leaf in leaves(value) for m in _PLACEHOLDER.finditer(str(leaf))}


def forces_replacement(type_: str, path: str) -> bool:
    """True when the rules of ``type_``'s Pulumi package say changing input ``path`` replaces the
    resource; a package without rules is assumed to update in place (the engine's preview has the last word)."""
    rules = registry.find(GROUP, type_.partition(":")[0])
    return rules is not None and bool(rules(type_, path))


def _input_changes(type_: str, before: Mapping[str, Any], after: Mapping[str, Any],
                   replaced: set[str]) -> list[InputChange]:
    old, new = dict(leaves(before)), dict(leaves(after))
    out = []
    for path in sorted(set(old) | set(new)):
        was, now = old.get(path), new.get(path)
        if was == now and _names(now) & replaced:
            now = KNOWN_AFTER_APPLY
        if was != now:
            out.append(InputChange(path, was, now, forces_replacement(type_, path)))
    return out


def _resources(before: Sequence[Mapping[str, Any]], after: Sequence[Mapping[str, Any]]) -> tuple[ResourceChange, ...]:
    def key(r: Mapping[str, Any]) -> tuple[str, str, str]:
        return (str(r["stack"]), str(r["type"]), str(r["name"]))

    old = {key(r): r for r in before}
    replaced: set[str] = set()
    result: dict[tuple[str, str, str], ResourceChange] = {}
    for _ in range(len(after) + 1):  # until no more replacements propagate (declaration order: usually one pass)
        grew = False
        for row in after:
            k = key(row)
            if k not in old:
                result[k] = ResourceChange(*k, action="create", inputs=row["inputs"])
                continue
            changes = _input_changes(k[1], old[k]["inputs"], row["inputs"], replaced)
            because = tuple(f"{c.path} changed" if c.after != KNOWN_AFTER_APPLY else
                            f"{c.path} refers to a replaced resource" for c in changes if c.forces_replacement)
            action: Action = "replace" if because else "update" if changes else "no-op"
            if action == "replace" and k[2] not in replaced:
                replaced.add(k[2])
                grew = True
            result[k] = ResourceChange(*k, action=action, changes=tuple(changes), because=because, inputs=row["inputs"])
        if not grew:
            break
    new = {key(r) for r in after}
    deletes = [ResourceChange(*key(r), action="delete", inputs=r["inputs"]) for r in before if key(r) not in new]
    return tuple(result[key(r)] for r in after) + tuple(deletes)


def _section(before: Sequence[Mapping[str, Any]] | None, after: Sequence[Mapping[str, Any]] | None,
             key: tuple[str, ...], *, compare: bool, content: str | None = None,
             ignore: tuple[str, ...] = ()) -> Section:
    """Rows keyed by ``key``; with ``compare``, rows on both sides report changed fields. ``content``: the field
    that digests what a row pushes: equal on both sides, the row's local path is no change (the same bytes
    reach the hosts from another member's checkout of the lab's repository, as a shared state store has it).
    ``ignore``: fields that follow from another section (a node's robots follow from the robots')."""
    if before is None or after is None:  # a version 1 document lacks this section: nothing to compare
        return Section()

    def k(row: Mapping[str, Any]) -> str:
        return " ".join(str(row.get(f)) for f in key)

    old, new = {k(r): r for r in before}, {k(r): r for r in after}
    changed = []
    if compare:
        for name in (n for n in new if n in old):
            # a field the older document did not have yet is not a change (an applied plan of an older fogiac)
            same = content is not None and old[name].get(content) == new[name].get(content)
            fields = tuple((f, old[name].get(f), new[name].get(f)) for f in new[name]
                           if f in old[name] and old[name].get(f) != new[name].get(f) and not (same and f == "path")
                           and f not in ignore)
            if fields:
                changed.append(RowChange(name, fields))
    return Section(added=tuple(r for n, r in new.items() if n not in old),
                   removed=tuple(r for n, r in old.items() if n not in new), changed=tuple(changed))


def _network(cidr: str) -> ipaddress.IPv4Network | ipaddress.IPv6Network | None:
    try:
        return ipaddress.ip_network(cidr, strict=False)
    except ValueError:
        return None  # the operator placeholder of an offline plan


# Topic names that command a robot's motion (geometry_msgs/Twist on /cmd_vel, trajectories, joint and motor
# commands, grippers, teleoperation): a new one from the cloud is flagged above the other exposure lines.
_ACTUATION = re.compile(r"(^|/|_)(cmd|cmd_vel|command|commands|twist|trajectory|joint_trajectory|velocity|effort|"
                        r"motor|motors|servo|actuator|actuators|gripper|teleop|drive|steer|steering|throttle|"
                        r"brake|goal|move_base|estop|e_stop)(_|/|$)", re.I)


def is_actuation(topic: str) -> bool:
    """A topic whose name says it moves the robot (``/cmd_vel``, ``/arm/joint_trajectory``, ``/gripper/command``)."""
    return bool(_ACTUATION.search(topic))


def _exposure(rules: Section, topics: Section) -> tuple[str, ...]:
    """Ingress rules added or widened, egress opened to the internet, and topics that now reach the robot."""
    lines = []
    removed = [r for r in rules.removed if r["direction"] == "ingress"]
    for rule in (r for r in rules.added if r["direction"] == "ingress"):
        where = f"{rule['group']} {rule['protocol']} {rule['ports']}"
        new = _network(str(rule["cidr"]))
        wider = [old for old in removed if (old["group"], old["protocol"], old["ports"]) ==
                 (rule["group"], rule["protocol"], rule["ports"]) and new is not None
                 and (net := _network(str(old["cidr"]))) is not None and net.version == new.version
                 and net != new and net.subnet_of(new)]  # type: ignore[arg-type]
        if wider:
            lines.append(f"CIDR widened: {where} from {wider[0]['cidr']} to {rule['cidr']} ({rule['description']})")
        else:
            lines.append(f"ingress added: {where} from {rule['cidr']} ({rule['description']})")
    for rule in (r for r in rules.added if r["direction"] == "egress"):
        if (net := _network(str(rule["cidr"]))) is not None and net.prefixlen == 0:
            lines.append(f"egress added to the internet: {rule['group']} {rule['protocol']} {rule['ports']} "
                         f"to {rule['cidr']} ({rule['description']})")
    actuation = []
    for topic in topics.added:
        if topic["direction"] in ("to_edge", "either") and is_actuation(str(topic["topic"])):
            way = "cloud -> robot" if topic["direction"] == "to_edge" else "in either direction"
            actuation.append(f"actuation topic added {way}: {topic['topic']} (host {topic['host']}): "
                             "what the cloud side publishes there moves the robot")
        elif topic["direction"] == "to_edge":
            lines.append(f"topic added cloud -> edge: {topic['topic']} (from host {topic['host']} to the robot)")
        elif topic["direction"] == "either":
            lines.append(f"topic added in either direction: {topic['topic']} (host {topic['host']}; "
                         "reaches the robot when the cloud side publishes it)")
    return tuple(actuation + lines)  # above everything else: a reviewer must not miss one


def edge_list(doc: Mapping[str, Any]) -> list[Mapping[str, Any]]:
    """A document's edges: its ``edges``, or the one edge named after the stack that ``edge_master`` describes."""
    listed = doc.get("edges")
    if isinstance(listed, list):
        return listed
    return [{"name": doc.get("stack"), "entry": doc.get("edge_master")}] if "edge_master" in doc else []


def _edges(before: Mapping[str, Any], after: Mapping[str, Any]) -> tuple[tuple[str, Any, Any], ...]:
    """``edges`` as a setting where either side lists them (else ``edge_master`` alone says any change)."""
    if "edges" not in before and "edges" not in after or "edge_master" not in before:
        return ()
    old, new = edge_list(before), edge_list(after)
    return (("edges", old, new),) if old != new else ()


# A node's fields that follow from the robots (whom ``serve: all`` serves, a per-robot node's instances, each robot's
# share of its hour): a robot added or removed shows in the robots section, not as every shared node changed.
ROBOT_FOLLOWED = ("serves", "instances", "usd_per_hour_per_robot")
# A robot's share of the hour follows every other robot's coming and going: the cost section says the total.
ROBOT_IGNORED = ("usd_per_hour",)


def robot_rows(doc: Mapping[str, Any]) -> list[Mapping[str, Any]] | None:
    """A fleet document's robots; None for a document without them (one robot, or nothing deployed)."""
    listed = doc.get("robots")
    return listed if isinstance(listed, list) else None


def _robots(before: Mapping[str, Any], after: Mapping[str, Any]) -> tuple[Section, bool]:
    """The robots added, removed and changed, and whether either side is a fleet. A side without ``robots``
    has none (a one-robot stack, nothing deployed), or lists its edges only (a fleet a fogiac before this one
    applied): those compare by name and entry."""
    old, new = robot_rows(before), robot_rows(after)
    if old is None and new is None:
        return Section(), False

    def edges(doc: Mapping[str, Any]) -> list[Mapping[str, Any]]:
        listed = doc.get("edges")
        return [row for row in listed if isinstance(row, Mapping)] if isinstance(listed, list) else []

    return _section(edges(before) if old is None else old, edges(after) if new is None else new, ("name",),
                    compare=True, ignore=ROBOT_IGNORED), True


def diff_documents(before: Mapping[str, Any] | None, after: Mapping[str, Any], *,
                   against: str = "applied") -> PlanDiff:
    """Everything that differs from ``before`` to ``after``; ``before`` None means nothing exists."""
    if before is None:
        before, against = {"resources": [], "hosts": [], "nodes": [], "topics": [], "security_rules": [],
                           "pushed": [], "cost": {"hourly_usd": 0.0}}, "nothing"
    rules = _section(before.get("security_rules"), after.get("security_rules"),
                     ("group", "direction", "protocol", "ports", "cidr"), compare=True)
    topics = _section(before.get("topics"), after.get("topics"), ("topic", "direction", "host"), compare=False)
    robots, fleet = _robots(before, after)
    settings = tuple((name, before.get(name), after.get(name)) for name in SETTINGS
                     if name in before and before.get(name) != after.get(name)) + _edges(before, after)
    return PlanDiff(
        against=against,
        resources=_resources(before.get("resources", []), after.get("resources", [])),
        hosts=_section(before.get("hosts"), after.get("hosts"), ("name",), compare=True),
        nodes=_section(_hidden_env(before.get("nodes")), after.get("nodes"), ("name",), compare=True,
                       ignore=ROBOT_FOLLOWED),
        topics=topics, security_rules=rules, settings=settings,
        cost_before=float(before.get("cost", {}).get("hourly_usd", 0.0)),
        cost_after=float(after.get("cost", {}).get("hourly_usd", 0.0)),
        unknown_before=len(before.get("cost", {}).get("unknown") or ()),
        unknown_after=len(after.get("cost", {}).get("unknown") or ()),
        exposure=_exposure(rules, topics),
        spot_before=_spot_hourly(before), spot_after=_spot_hourly(after),
        # an applied document recorded before pushed paths were listed: nothing to compare them with
        pushed=_section(before.get("pushed"), after.get("pushed"), ("node", "what"), compare=True, content="sha256")
        if "pushed" in before else Section(),
        cost_risk=_cost_risk(before.get("autostop"), after.get("autostop")) if "autostop" in before else (),
        autostop=after.get("autostop"), autostop_known="autostop" in after,
        spot_as_of=str((after.get("cost", {}).get("spot_prices") or before.get("cost", {}).get("spot_prices")
                        or {}).get("as_of", "")),
        robots=robots, fleet=fleet,
    )


def autostop_words(stop: Mapping[str, Any] | None) -> str:
    """The autostop in force, in words: "stops the hosts after 30 idle minutes", or that it is off."""
    if stop is None:
        return "autostop off: the hosts run (and cost) until `fogiac down`"
    minutes = f"{float(stop['idle_minutes']):g} idle minute{'s' if float(stop['idle_minutes']) != 1 else ''}"
    if stop.get("power") == "services":
        return f"autostop stops fogiac's services after {minutes} (the machines themselves keep running)"
    verb = "terminates the hosts (their disks deleted)" if stop.get("action") == "terminate" else "stops the hosts"
    return f"autostop {verb} after {minutes}"


def _cost_risk(before: Mapping[str, Any] | None, after: Mapping[str, Any] | None) -> tuple[str, ...]:
    """An autostop turned off, waiting longer, or stopping only services where it powered the machine off:
    the stack costs more while nobody uses it (flagged as a widened CIDR is an exposure)."""
    if before is None or before == after:
        return ()
    was, now = autostop_words(before), autostop_words(after)
    if after is None:
        return (f"autostop turned off: was {was.removeprefix('autostop ')}; now the hosts run until `fogiac down`",)
    lines = []
    if float(after["idle_minutes"]) > float(before["idle_minutes"]):
        lines.append(f"autostop waits longer: {float(before['idle_minutes']):g} -> {float(after['idle_minutes']):g} "
                     "idle minutes")
    if before.get("power") == "machine" and after.get("power") == "services":
        lines.append(f"autostop no longer powers the machines off: {was} -> {now}")
    return tuple(lines)


def _hidden_env(nodes: Any) -> Any:
    """Node rows with their env as plans show it now: an applied document recorded before values were
    hidden held them whole; compared as digests they show no spurious change (and no value)."""
    if not isinstance(nodes, list):
        return nodes
    return [{**row, "env": shown_env(row["env"])} if isinstance(row, Mapping) and isinstance(row.get("env"), Mapping)
            else row for row in nodes]


def _spot_hourly(doc: Mapping[str, Any]) -> float | None:
    spot = doc.get("cost", {}).get("spot_hourly_usd")
    return None if spot is None else float(spot)


def with_drift(diff: PlanDiff, drift: tuple[Drift, ...], *, refreshed_at: str) -> PlanDiff:
    """``diff`` with what the last refresh found; an ingress rule made outside fogiac widens exposure too."""
    opened = tuple(f"ingress added outside fogiac: {d.detail}" for d in drift
                   if d.status == "added" and d.type.endswith("IngressRule"))
    return dataclasses.replace(diff, drift=drift, refreshed_at=refreshed_at, exposure=diff.exposure + opened)


def annotate(doc: Mapping[str, Any], diff: PlanDiff) -> dict[str, Any]:
    """``doc`` as ``plan --json`` prints it: each resource's action, ``before``/``after`` of the
    changed inputs for updates and replacements, deleted resources last, and ``changes``."""
    rows = []
    for change in diff.resources:
        row: dict[str, Any] = {"stack": change.stack, "type": change.type, "name": change.name,
                               "action": change.action, "inputs": dict(change.inputs)}
        if change.action in ("update", "replace"):
            row["before"] = {c.path: c.before for c in change.changes}
            row["after"] = {c.path: c.after for c in change.changes}
            row["replace_because"] = list(change.because)
        rows.append(row)
    return {**doc, "resources": rows, "changes": diff.to_dict()}
