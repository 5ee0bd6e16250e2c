"""The Plan: everything later stages need, computed once from a Manifest by :mod:`fogiac.plan.compile`.

Frozen dataclasses only (no pydantic, no Pulumi), so the Plan is cheap to build, compare and
serialise. ``to_dict`` gives a stable, JSON-ready form: same manifest, same bytes.
"""

from __future__ import annotations

import dataclasses
import hashlib
import ipaddress
import json
import typing
from dataclasses import dataclass, field
from typing import Any, Literal

from fogiac.errors import PlanError
from fogiac.manifest.machines import Option, RankedBy

# Ports. ROS 1 masters listen on 11311; nodes on ephemeral ports, which Linux takes from
# 32768-60999 by default; the middleware's end on a host that picks no port of its own on RELAY_PORT
# (the relay's cloud end: fogiac.net.relay.config takes it from here).
SSH_PORT = 22
ROS_MASTER_PORT = 11311
RELAY_PORT = 11411
ROS_EPHEMERAL = (32768, 60999)
OPERATOR = "operator"  # stands for the operator's address in ssh_from: auto until preflight resolves it
OPERATOR_PLACEHOLDER = "<operator>/32"  # what an offline plan shows for the operator's address

Protocol = Literal["tcp", "udp", "icmp", "-1"]  # "-1": every protocol (AWS's spelling)
NodeKind = Literal["image", "launch", "workload", "command"]
NetworkMode = Literal["vpn", "proxy", "relay"]  # how the edge reaches the hosts
ConnectVia = Literal["private", "public", "address", "loopback"]  # which host address the edge relay dials


@dataclass(frozen=True)
class EdgeSpec:
    """One robot's side of the stack: who it is, and where its ROS graph is reached.

    ``name`` is the edge's identity: its client certificate (the relay's cloud ends and the Zenoh routers
    tell edges apart by it), and its processes' and files' names on this machine. Today's manifests make one
    edge from their ``edge:`` block, named after the stack (``shorthand``): its certificate, files and
    processes keep the names they had before edges were a list, so a stack folder of then keeps working.
    """

    name: str
    entry: str  # its ROS 1 master URI, or the edge Zenoh router's endpoint
    shorthand: bool = False  # the manifest's one-robot ``edge:`` block made it (see above)
    compression: str | None = None  # a fleet robot's own relay compression for every topic (None: the routes')

    @property
    def named(self) -> str | None:
        """The name its certificate and files carry: None for the shorthand edge, which keeps those of before."""
        return None if self.shorthand else self.name


@dataclass(frozen=True)
class Rule:
    """One security-group rule; ``cidr`` is a CIDR or the OPERATOR placeholder."""

    protocol: Protocol
    from_port: int
    to_port: int
    cidr: str
    description: str


def check_ingress(group: str, rules: tuple[Rule, ...]) -> None:
    """The invariant every plan and every stack keeps: no ingress from 0.0.0.0/0 or ::/0.

    The one implementation: every :class:`SecurityGroup` checks its own rules when it is made (so a
    plan, whatever target placed it, holds none), and the firewall stack checks again the rules it is
    about to create, once the operator's address is filled in.
    """
    for rule in rules:
        if rule.cidr in (OPERATOR, OPERATOR_PLACEHOLDER):
            continue
        try:
            network = ipaddress.ip_network(rule.cidr, strict=False)
        except ValueError:
            raise PlanError(f"security group {group!r}: {rule.cidr!r} is not a CIDR") from None
        if network.prefixlen == 0:
            raise PlanError(f"security group {group!r} would accept {rule.cidr} on port {rule.from_port}")


@dataclass(frozen=True)
class SecurityGroup:
    name: str
    description: str
    ingress: tuple[Rule, ...]
    egress: tuple[Rule, ...]

    def __post_init__(self) -> None:
        check_ingress(self.name, self.ingress)  # no group open to the world can exist, whoever makes it


class NetworkSpec(typing.Protocol):
    """The network the target puts the hosts in, its own part of the plan (the aws target's VPC and
    subnets: ``fogiac.targets.aws.model.VpcSpec``); None where the target has none of its own. What
    every target says about reaching the hosts is the plan's own (``mode``, ``ssh_from``,
    ``security_groups``, ``routes``); neutral code asks only whether there is a network. The plan
    document holds what ``document`` makes of its ``dataclasses.asdict``."""

    def document(self, fields: dict[str, Any]) -> dict[str, Any]:
        """Its fields as the plan document (and so the plan's digest) holds them."""


class EdgeVpn(typing.Protocol):
    """The target's VPN for the edge, its part of the plan (the aws target's Client VPN endpoint:
    ``fogiac.targets.aws.model.VpnSpec``); neutral code asks only whether there is one, and its name."""

    @property
    def label(self) -> str: ...


class MachineImage(typing.Protocol):
    """How the target finds a host's disk image (on aws an AMI query); the plan shows its description."""

    @property
    def description(self) -> str: ...


@dataclass(frozen=True)
class LaunchSpec:
    package: str
    file: str
    workspace: str
    env_script: str | None
    requirements: str | None = None  # a pip requirements file, read when the host is provisioned


@dataclass(frozen=True)
class BuildSpec:
    context: str
    dockerfile: str


@dataclass(frozen=True)
class NodeSpec:
    name: str
    host: str
    kind: NodeKind
    image: str | None
    command: tuple[str, ...]
    launch: LaunchSpec | None
    workload: str | None
    gpu: bool
    env: tuple[tuple[str, str], ...]
    topics_auto: bool
    topics_in: tuple[str, ...]
    topics_out: tuple[str, ...]
    build: BuildSpec | None = None
    # (NAME, reference): env values read at `up` (env:NAME, file:PATH), never held in the plan
    secrets: tuple[tuple[str, str], ...] = ()
    serves: tuple[str, ...] = ()  # in a fleet, the robots it serves when not every one (the manifest's serve: list)
    per_robot: bool = False  # serve: per_robot, one instance for each robot it serves, in that robot's namespace
    reply_match: str | None = None  # in a fleet, the reply field naming its request (routes replies to the asker)


@dataclass(frozen=True)
class HostSpec:
    """One machine: an EC2 instance on ``aws``, a lab machine on ``hosts``, a sandbox on ``local``."""

    name: str
    machine: str
    vcpus: int
    gpus: int
    memory_gib: float
    usd_per_hour: float | None  # on-demand: what a spot host costs at most; None: unknown (no price there)
    spot: bool
    disk_gb: int
    nodes: tuple[str, ...]
    steps: tuple[str, ...]
    tags: tuple[tuple[str, str], ...]
    image: MachineImage | None = None
    chosen_for: str | None = None  # the node's requirement in words, when compile chose the machine
    alternatives: tuple[Option, ...] = ()  # the next cheapest types that also fit
    ranked_by: RankedBy | None = None  # which price chose the machine (spot for a spot host); None: named
    spot_usd_per_hour: float | None = None  # a spot host's catalogue spot estimate (None: on-demand, or unknown)
    address: str | None = None
    user: str | None = None
    port: int | None = None
    key: str | None = None
    runtime: Literal["auto", "container", "native"] = "auto"  # auto: containers where `docker info` answers
    # The host's ROS master and relay ports: the fixed ones on machines of their own (aws), the
    # stack's own on shared machines (hosts), so two stacks on one lab machine never meet.
    master_port: int = ROS_MASTER_PORT
    relay_port: int | None = None  # None: the middleware's port
    zone: str | None = None  # None: the plan's zone; set for a replica's host (aws: one zone per replica)

    @property
    def has_gpu(self) -> bool:
        return self.gpus > 0


HedgeMode = Literal["all", "delayed"]  # every request to every replica at once, or to the others after a delay


@dataclass(frozen=True)
class Replica:
    """One of a replicated node's copies, each on a host of its own: the edge sends each request to every
    live replica (``hedge``) and hands the robot the first reply to each request, never a duplicate."""

    group: str  # the replicated node's name: the routes of one group are merged at the edge
    index: int  # 0 .. count - 1; 0 is the one a "delayed" hedge asks first
    count: int
    match: str  # how a reply names its request: "header.stamp" (a std_msgs/Header's stamp, the default) or a field
    hedge: HedgeMode = "all"
    hedge_delay_s: float = 0.0  # "delayed": how long the first replica has before the others are asked too
    types: tuple[tuple[str, str], ...] = ()  # (topic, message type) as message_types states: replies checked with it


@dataclass(frozen=True)
class Route:
    """What crosses between the edge and one host, and where the edge dials it (whichever middleware)."""

    host: str
    connect_via: ConnectVia  # private (through the VPN), public (proxy mode), address (hosts), loopback (local)
    port: int
    auto: bool  # discover topics from both masters
    to_cloud: tuple[str, ...]  # nodes' "in" topics: robot -> cloud
    to_edge: tuple[str, ...]  # nodes' "out" topics: cloud -> robot
    listed: tuple[str, ...]  # relay.topics: relayed in whichever direction has the publisher
    compression: tuple[tuple[str, str], ...]  # ("*", alg) for all topics, or per topic
    queue_size: int
    replica: Replica | None = None  # set when the host carries one copy of a replicated node (and nothing else)

    def policy_argv(self) -> list[str]:
        """``--out/--in/--topics`` for ``fogiac relay edge|cloud``: both ends enforce the same
        policy. The manifest's "in" (robot -> node) is what the edge sends out, its "out" what
        comes in."""
        argv = ["--out", ",".join(self.to_cloud)] if self.to_cloud else []
        argv += ["--in", ",".join(self.to_edge)] if self.to_edge else []
        if self.auto or self.listed:
            argv += ["--topics", "auto" if self.auto else ",".join(self.listed)]
        else:
            argv += ["--topics", ""]  # nothing beyond the lists: not the CLI's default of auto
        return argv


RelayRoute = Route  # the former name, until every caller says Route


AutostopPower = Literal["machine", "services"]  # power the machine off, or stop fogiac's services on it


@dataclass(frozen=True)
class AutostopSpec:
    """When a host stops itself, and how: decided by the target at compile time."""

    idle_s: float
    action: Literal["stop", "terminate"]  # what a powered-off machine becomes (the compute stack sets it)
    power: AutostopPower


@dataclass(frozen=True)
class CostLine:
    item: str
    quantity: float
    usd_per_hour: float | None  # on-demand; None: the catalogue has no price there (unknown, never $0)
    spot_usd_per_hour: float | None = None  # the catalogue's spot estimate, for a spot instance
    per_robot: bool = False  # one of its quantity per robot of a fleet (aws: its Client VPN connection): each bears one

    @property
    def known(self) -> bool:
        return self.usd_per_hour is not None

    @property
    def total(self) -> float:
        """The line's on-demand total; 0 for an unknown price, which every total counts apart (``unknown``)."""
        return round(self.quantity * (self.usd_per_hour or 0.0), 4)

    @property
    def spot_total(self) -> float:
        """What the line costs at the spot estimate (the on-demand total where there is none)."""
        each = self.usd_per_hour if self.spot_usd_per_hour is None else self.spot_usd_per_hour
        return round(self.quantity * (each or 0.0), 4)


@dataclass(frozen=True)
class Plan:
    stack: str
    manifest_name: str
    environment: str
    target: str
    region: str
    zone: str
    zone_chosen: bool  # True when the manifest named the zone
    ros_distro: str
    middleware: str  # fogiac.net.middleware's name for what carries topics across (relay, zenoh)
    mode: NetworkMode
    edges: tuple[EdgeSpec, ...]  # the robots' sides, each with its identity; today's manifests make one
    ssh_from: tuple[str, ...]
    network: NetworkSpec | None
    security_groups: tuple[SecurityGroup, ...]
    vpn: EdgeVpn | None
    hosts: tuple[HostSpec, ...]
    nodes: tuple[NodeSpec, ...]
    routes: tuple[Route, ...]  # what crosses between the edge and each host, in the middleware's neutral terms
    tags: tuple[tuple[str, str], ...]
    cost: tuple[CostLine, ...] = field(default=())
    autostop: AutostopSpec | None = None
    # The manifest's block the middleware owns (a plug-in's ``beacon:``), JSON-ready, for its deployment.
    middleware_settings: tuple[tuple[str, Any], ...] = ()
    notes: tuple[str, ...] = ()  # what placement decided that a reader should know (replicas' zones, ...)
    # Private registries the hosts log in to: (server, username, the password's secret reference)
    registries: tuple[tuple[str, str, str], ...] = ()
    budget_usd_per_hour: float | None = None  # cloud.budget_usd_per_hour: what `up` lets the plan cost an hour

    def __post_init__(self) -> None:
        names = [edge.name for edge in self.edges]
        if not names:
            raise PlanError(f"stack {self.stack}: a plan needs at least one edge")
        if len(set(names)) != len(names):
            raise PlanError(f"stack {self.stack}: two edges named {next(n for n in names if names.count(n) > 1)!r}")

    @property
    def edge_master(self) -> str:
        """The first edge's entry: the only one while manifests make one edge (``up --edge-master`` overrides it)."""
        return self.edges[0].entry

    def is_default_edge(self, edge: EdgeSpec) -> bool:
        """Whether ``edge`` is the one today's manifests make (``edge:``, named after the stack): its certificate
        and processes keep the file names they had before edges were a list, so a stack folder of then works."""
        return edge.shorthand

    @property
    def fleet(self) -> bool:
        """Whether the manifest listed its robots (``robots:``): each then has its own namespace and access."""
        return not self.edges[0].shorthand

    def robots_of(self, node: NodeSpec) -> tuple[str, ...]:
        """The robots ``node`` serves (every one unless its ``serve:`` lists some)."""
        return node.serves or tuple(edge.name for edge in self.edges)

    def edges_at(self, entry: str | None = None) -> tuple[EdgeSpec, ...]:
        """The edges, the first reached at ``entry`` when given (``up --edge-master``, a test's own master)."""
        if entry is None or entry == self.edges[0].entry:
            return self.edges
        return (dataclasses.replace(self.edges[0], entry=entry),) + self.edges[1:]

    @property
    def hourly_usd(self) -> float:
        """On-demand prices throughout: the most the plan costs an hour."""
        return round(sum(line.total for line in self.cost), 4)

    @property
    def unknown_costs(self) -> tuple[str, ...]:
        """The cost lines whose price is unknown: every total is then "at least" what it says, never exact."""
        return tuple(line.item for line in self.cost if not line.known)

    @property
    def spot_hourly_usd(self) -> float | None:
        """The hour with spot hosts at their spot estimate; None when no line has one."""
        if all(line.spot_usd_per_hour is None for line in self.cost):
            return None
        return round(sum(line.spot_total for line in self.cost), 4)

    def host(self, name: str) -> HostSpec:
        for host in self.hosts:
            if host.name == name:
                return host
        raise KeyError(name)

    def node(self, name: str) -> NodeSpec:
        for node in self.nodes:
            if node.name == name:
                return node
        raise KeyError(name)

    def to_dict(self) -> dict[str, Any]:
        out = dataclasses.asdict(self)
        out["relay"] = out.pop("routes")  # the document's key since version 1: applied plans compare as before
        for route in out["relay"]:
            if route["replica"] is None:  # unreplicated: the same bytes (and digest) as before replicas existed
                del route["replica"]
            elif not route["replica"]["types"]:  # no stated types: the same bytes as before they were carried
                del route["replica"]["types"]
        for line in out["cost"]:
            if not line["per_robot"]:  # shared: the same bytes (and digest) as before a robot bore its own line
                del line["per_robot"]
        for host in out["hosts"]:
            if host["zone"] is None:  # absent unless set: existing plans keep their bytes (and digests)
                del host["zone"]
        if self.network is not None:
            out["network"] = self.network.document(out["network"])
        if not self.notes:
            del out["notes"]
        for node in out["nodes"]:
            if not node["secrets"]:  # none: the same bytes (and digest) as before secrets could be named
                del node["secrets"]
            if not node["serves"]:  # every robot: the same bytes (and digest) as before fleets
                del node["serves"]
            if not node["per_robot"]:  # one shared instance: the same bytes (and digest) as before per_robot
                del node["per_robot"]
            if node["reply_match"] is None:  # one robot: the same bytes (and digest) as before fleets
                del node["reply_match"]
        for edge in out["edges"]:
            if edge["compression"] is None:  # the routes' own: the same bytes as before a robot could name one
                del edge["compression"]
        if not self.registries:  # none: the same bytes (and digest) as before registries could be named
            del out["registries"]
        if not self.middleware_settings:  # none: the same bytes (and digest) as before there could be any
            del out["middleware_settings"]
        if len(self.edges) == 1 and self.edges[0].shorthand:
            del out["edges"]  # the one edge of today's manifests: the same bytes (and digest) as before edges
            out["edge_master"] = self.edge_master
        if self.budget_usd_per_hour is None:  # no budget: the same bytes (and digest) as before there could be one
            del out["budget_usd_per_hour"]
        out["hourly_usd"] = self.hourly_usd
        return out

    def digest(self) -> str:
        """A fingerprint of the whole plan: equal plans, equal digests."""
        text = json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()
