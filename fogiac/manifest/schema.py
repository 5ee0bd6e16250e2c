"""The manifest (``fogiac.yaml``): typed, frozen, validated.

:func:`load_manifest` is the only code that sees raw YAML. Every problem it finds becomes one
line ``PATH:LINE: field.path: what is wrong`` (with a "did you mean" where one is close), all
of them at once, raised as :class:`~fogiac.errors.ManifestError`.
"""

from __future__ import annotations

import ipaddress
import re
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal
from urllib.parse import urlparse

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    ValidationInfo,
    ValidatorFunctionWrapHandler,
    WrapValidator,
    field_validator,
    model_validator,
)
from pydantic_core import InitErrorDetails, PydanticCustomError

from fogiac import registry
from fogiac.errors import ManifestError
from fogiac.manifest.clouds import CloudVariant, known, providers, variant
from fogiac.manifest.crossfield import cross_field_problems
from fogiac.manifest.machines import Choice, NoMachine, Requirement, parse_bound
from fogiac.manifest.problems import FieldProblem, format_errors, line_index, parse_yaml
from fogiac.manifest.requirements import RequirementsProblem, specifiers

_DNS_NAME = re.compile(r"^[a-z]([a-z0-9-]{0,38}[a-z0-9])?$")
_TOPIC = re.compile(r"^/[A-Za-z][A-Za-z0-9_/]*$")
_ENV_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
# An OCI image reference: [registry[:port]/]path[:tag][@digest], lowercase path components.
_IMAGE_REF = re.compile(
    r"^(?:[A-Za-z0-9](?:[A-Za-z0-9.-]*[A-Za-z0-9])?(?::[0-9]+)?/)?"
    r"[a-z0-9]+(?:(?:[._]|__|-+)[a-z0-9]+)*(?:/[a-z0-9]+(?:(?:[._]|__|-+)[a-z0-9]+)*)*"
    r"(?::[A-Za-z0-9_][A-Za-z0-9_.-]{0,127})?(?:@sha256:[0-9a-f]{64})?$"
)
_MIN_SUBNET_PREFIX = 27
# ssh_from may cover at most a /8 (16.7 M addresses) in all: the largest block one organisation
# holds (the legacy /8s); anything wider is not "my network" but a share of the whole internet,
# and /1 pairs would otherwise slip past a check for 0.0.0.0/0 alone.
SSH_FROM_MAX_PREFIX = 8
_USER = re.compile(r"^[a-z_][a-z0-9_-]{0,31}$")  # POSIX user names as useradd takes them
_HOST_LABEL = re.compile(r"^(?!-)[A-Za-z0-9-]{1,63}(?<!-)$")


def ssh_from_problem(nets: Iterable[ipaddress.IPv4Network]) -> str | None:
    """Why these CIDRs are too wide to open SSH (and the relay) to, or None."""
    given = list(nets)
    covered = sum(n.num_addresses for n in ipaddress.collapse_addresses(given))
    if covered > 2 ** (32 - SSH_FROM_MAX_PREFIX):
        return (f"{', '.join(str(n) for n in given)} cover {covered} addresses, more than a "
                f"/{SSH_FROM_MAX_PREFIX} ({2 ** (32 - SSH_FROM_MAX_PREFIX)}); name your own network")
    return None


def _sizing(info: ValidationInfo | None) -> CloudVariant:
    """The ``cloud:`` variant that names the machines: the manifest's provider's, which
    :func:`parse_manifest` passes as context; without one (a model built in code), the default's."""
    context = info.context if info is not None else None
    return variant(context.get("provider") if isinstance(context, dict) else None)


def _no_control(value: Path) -> Path:
    if any(ord(c) < 32 or ord(c) == 127 for c in str(value)):
        raise ValueError(f"{str(value)!r} contains a control character")
    return value


PlainPath = Annotated[Path, AfterValidator(_no_control)]


def _user(value: str) -> str:
    if not _USER.match(value):
        raise ValueError(f"{value!r} is not a user name (lowercase letters, digits, '_', '-', up to 32)")
    return value


def _address(value: str) -> str:
    try:
        ipaddress.ip_address(value)
        return value
    except ValueError:
        pass
    if len(value) <= 253 and all(_HOST_LABEL.match(label) for label in value.split(".")):
        return value
    raise ValueError(f"{value!r} is not an IP address or host name (letters, digits, '-', dots)")

Compression = Literal["none", "zstd", "lz4"]


class _Model(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", populate_by_name=True)


def _topic(value: str) -> str:
    if not _TOPIC.match(value) or "//" in value or value.endswith("/"):
        raise ValueError(f"{value!r} is not a ROS topic name (absolute, like '/camera/depth')")
    return value


Topic = Annotated[str, Field(description="An absolute ROS topic name, e.g. /camera/depth")]


def _dns_name(value: str) -> str:
    if not _DNS_NAME.match(value):
        raise ValueError(f"{value!r} is not DNS-safe (lowercase letters, digits, '-', up to 40)")
    return value


DnsName = Annotated[str, AfterValidator(_dns_name)]


def _served(value: object, handler: ValidatorFunctionWrapHandler) -> object:
    """A distribution an installed middleware serves (entry point group ``fogiac.middlewares``); the
    middlewares are asked only for a name that is not fogiac's own, so ``validate`` stays fast."""
    try:
        return handler(value)
    except ValidationError:
        if isinstance(value, str) and value in registry.load("fogiac.middleware", "distros")():
            return value
        raise


def _contributed(value: object, handler: ValidatorFunctionWrapHandler) -> object:
    """A provider an installed package contributes (entry point group ``fogiac.clouds``); the
    distributions are read only for a name that is not built in, so ``validate`` stays fast."""
    try:
        return handler(value)
    except ValidationError:
        if isinstance(value, str) and value in providers():
            return value
        raise


if TYPE_CHECKING:
    Distro = str
    Provider = str
else:  # fogiac's own middlewares' distributions, and (_served) one another installed middleware serves;
    # on the type, not the field, so the checks across fields (crossfield.py) admit it too
    Distro = Annotated[Literal["noetic", "humble", "jazzy", "kilted"], WrapValidator(_served)]
    # fogiac's own targets' ``cloud:`` variants, and (_contributed) another installed package's
    Provider = Annotated[Literal[providers(own=True)], WrapValidator(_contributed)]


class Ros(_Model):
    distro: Distro = Field(
        default="noetic",
        description="ROS distribution: noetic (ROS 1, fogiac's relay) or humble, jazzy, kilted (ROS 2, Zenoh).",
    )


class HostMachine(_Model):
    """An existing machine for the ``hosts`` target (a lab GPU server is fog too)."""

    name: DnsName = Field(description="Short DNS-safe name for the machine.")
    address: Annotated[str, AfterValidator(_address)] = Field(description="IP address or DNS name reachable over SSH.")
    user: Annotated[str, AfterValidator(_user)] = Field(default="ubuntu", description="SSH user.")
    port: int = Field(default=22, ge=1, le=65535, description="SSH port.")
    key: PlainPath = Field(description="Private key file for SSH, relative to the manifest.")
    gpus: int = Field(default=0, ge=0, description="GPUs the machine has.")


class Autostop(_Model):
    """Stop (or terminate) cloud hosts nobody uses: no edge connected and no message for idle_minutes."""

    idle_minutes: float = Field(default=30, gt=0, description="Minutes without an edge and without traffic.")
    action: Literal["stop", "terminate"] = Field(
        default="stop", description="stop: keep the disk, `up` starts it again; terminate: delete the machine."
    )


class Cloud(_Model):
    provider: Provider = Field(default="aws", description="Where cloud nodes run.")
    region: str = Field(default="us-west-2", description="AWS region (one the price table covers).")
    zone: str | None = Field(default=None, description="Availability zone; chosen by preflight if absent.")
    hosts: tuple[HostMachine, ...] = Field(default=(), description="Machines for the hosts target.")
    autostop: Literal["off"] | Autostop | None = Field(
        default=None, description="Idle shutdown; unset: the target's default (aws: 30 idle minutes, stop); off: never."
    )

    @field_validator("autostop", mode="before")
    @classmethod
    def _yaml_off(cls, value: object) -> object:
        """YAML 1.1 reads a bare ``off`` as false: that is the ``off`` the user wrote."""
        return "off" if value is False else value
    runtime: Literal["auto", "container", "native"] = Field(
        default="auto",
        description="How nodes run on local and hosts machines: in containers (podman, or a docker that answers), "
        "natively, or auto (containers where `docker info` answers).",
    )

    @field_validator("region")
    @classmethod
    def _region(cls, value: str, info: ValidationInfo) -> str:
        variant(info.data.get("provider")).check_region(value)  # the provider's own regions and words
        return value

    def chosen(self) -> str | None:
        """The provider, or None while it has a problem (the checks across fields then ask the default's
        variant, whose words every built-in variant shares, rather than skip)."""
        return self.provider if isinstance(self.provider, str) else None

    @model_validator(mode="after")
    def _zone_in_region(self) -> Cloud:
        if self.zone is not None:
            variant(self.chosen()).check_zone(self.zone, self.region)
        names = [h.name for h in self.hosts]
        for i, name in enumerate(names):
            if name in names[:i]:
                raise FieldProblem(f"duplicate host name {name!r}", field=f"hosts[{i}].name")
        return self


class Network(_Model):
    mode: Literal["vpn", "proxy"] = Field(
        default="vpn", description="vpn: the edge joins the target's VPN; proxy: relay over TLS to the public address."
    )
    vpc_cidr: ipaddress.IPv4Network = Field(
        default=ipaddress.IPv4Network("10.10.0.0/16"), description="VPC address range (/16 to /26)."
    )
    client_cidr: ipaddress.IPv4Network = Field(
        default=ipaddress.IPv4Network("10.200.0.0/22"),
        description="The edge's VPN address range (the target's VPN sets its limits), outside the VPC.",
    )
    ssh_from: Literal["auto"] | tuple[ipaddress.IPv4Network, ...] = Field(
        default="auto", description="CIDRs allowed to SSH (and, in proxy mode, reach the relay); auto: your address."
    )
    egress_tcp: tuple[int, ...] = Field(
        default=(80, 443), description="TCP ports the hosts may open to the internet (packages, images); "
        "DNS and time use the VPC's resolver and Amazon Time Sync, which security groups do not filter."
    )
    flow_logs: bool = Field(
        default=False, description="VPC flow logs to a CloudWatch log group that goes with the stack (billed per GB)."
    )

    @field_validator("egress_tcp")
    @classmethod
    def _ports(cls, value: tuple[int, ...]) -> tuple[int, ...]:
        for port in value:
            if not 1 <= port <= 65535:
                raise ValueError(f"{port} is not a TCP port (1-65535)")
        return tuple(sorted(set(value)))

    @field_validator("vpc_cidr")
    @classmethod
    def _vpc(cls, value: ipaddress.IPv4Network) -> ipaddress.IPv4Network:
        if not 16 <= value.prefixlen <= _MIN_SUBNET_PREFIX - 1:
            raise ValueError(
                f"{value} must be between /16 and /{_MIN_SUBNET_PREFIX - 1} "
                f"(it holds two subnets of at least /{_MIN_SUBNET_PREFIX})"
            )
        return value

    @field_validator("client_cidr")
    @classmethod
    def _client(cls, value: ipaddress.IPv4Network, info: ValidationInfo) -> ipaddress.IPv4Network:
        _sizing(info).check_edge_vpn_range(str(value), value.prefixlen)  # the target's VPN says what it allows
        return value

    @field_validator("ssh_from")
    @classmethod
    def _no_world(cls, value: object) -> object:
        if isinstance(value, tuple):
            for net in value:
                if net.prefixlen == 0:
                    raise ValueError(f"{net} opens SSH to the whole internet; name your own network")
            problem = ssh_from_problem(value)
            if problem:
                raise ValueError(problem)
        return value

    @model_validator(mode="after")
    def _no_overlap(self) -> Network:
        if self.mode == "vpn" and self.client_cidr.overlaps(self.vpc_cidr):
            raise FieldProblem(
                f"{self.client_cidr} overlaps vpc_cidr {self.vpc_cidr}", field="client_cidr"
            )
        return self


class Edge(_Model):
    ros_master: str = Field(
        default="http://localhost:11311", description="The robot's ROS master URI (ROS_MASTER_URI), ROS 1."
    )
    zenoh_router: str = Field(
        default="tcp/127.0.0.1:7447",
        description="ROS 2: where fogiac's edge router listens for the robot's rmw_zenoh nodes (loopback).",
    )

    @field_validator("ros_master")
    @classmethod
    def _uri(cls, value: str) -> str:
        url = urlparse(value)
        if url.scheme != "http" or not url.hostname or url.port is None:
            raise ValueError(f"{value!r} is not a ROS master URI like 'http://localhost:11311'")
        return value

    @field_validator("zenoh_router")
    @classmethod
    def _endpoint(cls, value: str) -> str:
        proto, _, rest = value.partition("/")
        host, _, port = rest.rpartition(":")
        if proto != "tcp" or not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise ValueError(f"{value!r} is not a Zenoh endpoint like 'tcp/127.0.0.1:7447'")
        return value


class Launch(_Model):
    package: str = Field(description="ROS package holding the launch file.")
    file: str = Field(description="Launch file name, e.g. planner.launch.")
    workspace: PlainPath = Field(description="Workspace folder to push, relative to the manifest.")
    env_script: PlainPath | None = Field(default=None, description="Script run once per change to set the host up.")
    requirements: PlainPath | None = Field(
        default=None, description="pip requirements file of the package's Python nodes, relative to the manifest: "
        "installed in the host's virtual environment (native) or in the node's image (container).")


class Build(_Model):
    context: Path = Field(description="Build context folder, relative to the manifest.")
    dockerfile: str = Field(default="Dockerfile", description="Dockerfile inside the context folder.")

    @field_validator("dockerfile")
    @classmethod
    def _inside(cls, value: str) -> str:
        if value.startswith("/") or ".." in Path(value).parts:
            raise ValueError(f"{value!r} must be a path inside the context folder")
        return value

    @model_validator(mode="after")
    def _dockerfile_exists(self) -> Build:
        if self.context.is_dir() and not (self.context / self.dockerfile).is_file():
            raise FieldProblem(f"{self.dockerfile!r} is not a file in {self.context}", field="dockerfile")
        return self


class TopicLists(_Model):
    inputs: tuple[Topic, ...] = Field(default=(), alias="in", description="Topics from the robot to this node.")
    outputs: tuple[Topic, ...] = Field(default=(), alias="out", description="Topics from this node to the robot.")

    _check = field_validator("inputs", "outputs")(
        classmethod(lambda cls, v: tuple(_topic(t) for t in v))
    )


class Machine(_Model):
    """What a node needs instead of a type name: compile picks the cheapest catalogue type that fits."""

    type: str | None = Field(default=None, description="A type from the target's catalogue; or leave it out.")
    gpu: bool | str | None = Field(default=None, description="true (any GPU) or a model such as T4, A10G, V100.")
    vcpus: int | str | None = Field(default=None, description="vCPUs: a number (at least) or a bound like '>=8'.")
    memory_gib: float | str | None = Field(default=None, description="Memory in GiB: a number (at least) or '>=16'.")

    @field_validator("vcpus", "memory_gib")
    @classmethod
    def _bound(cls, value: int | float | str | None) -> int | float | str | None:
        if value is not None:
            parse_bound(value)
        return value

    @field_validator("type")
    @classmethod
    def _type(cls, value: str | None, info: ValidationInfo) -> str | None:
        if value is not None:
            _sizing(info).check_machine(value)
        return value

    @model_validator(mode="after")
    def _type_or_needs(self) -> Machine:
        needs = [k for k in ("gpu", "vcpus", "memory_gib") if getattr(self, k) is not None]
        if self.type is not None and needs:
            raise FieldProblem(f"give either type or requirements ({', '.join(needs)}), not both")
        if self.type is None and not needs:
            raise FieldProblem("needs a type or at least one of gpu, vcpus, memory_gib")
        return self

    def requirement(self, *, gpu: bool = False) -> Requirement:
        """The requirement; ``gpu`` (the node's own flag) asks for any GPU when none is named."""
        return Requirement(
            gpu=self.gpu if self.gpu not in (None, False) else (True if gpu else None),
            vcpus=parse_bound(self.vcpus) if self.vcpus is not None else None,
            memory_gib=parse_bound(self.memory_gib) if self.memory_gib is not None else None,
        )


if TYPE_CHECKING:
    Workload = str
else:  # the workloads fogiac ships (entry points of fogiac.workloads that fogiac itself declares)
    Workload = Literal[registry.names("fogiac.workloads", own=True)]
NodeKind = Literal["image", "launch", "workload", "command"]  # which of the four a node runs


class Node(_Model):
    name: DnsName = Field(description="DNS-safe node name, unique in the manifest.")
    machine: str | Machine = Field(
        description="Machine type (c5.24xlarge), or what the node needs ({gpu: T4, vcpus: '>=8'})."
    )
    image: str | None = Field(
        default=None, description="Container image to run (exactly one of image, build, launch, workload)."
    )
    build: Build | None = Field(default=None, description="Container image built on the host from a Dockerfile.")
    launch: Launch | None = Field(default=None, description="ROS package + launch file from a workspace.")
    workload: Workload | None = Field(default=None, description="A workload that ships with fogiac.")
    command: tuple[str, ...] = Field(
        default=(), description="Arguments after the image; alone: a command run as the node (in the ROS image "
        "on container hosts)."
    )
    gpu: bool = Field(default=False, description="The node needs a GPU.")
    topics: Literal["auto"] | TopicLists = Field(default="auto", description="Topics relayed for this node.")
    disk_gb: int = Field(default=30, ge=8, le=16384, description="Root volume size in GiB (gp3, encrypted).")
    spot: bool = Field(default=False, description="Use a spot instance.")
    env: dict[str, str] = Field(default_factory=dict, description="Environment variables for the node.")
    host: str | None = Field(default=None, description="For the hosts target: which cloud.hosts entry runs it.")

    @field_validator("machine")
    @classmethod
    def _machine(cls, value: str | Machine, info: ValidationInfo) -> str | Machine:
        if isinstance(value, str):
            _sizing(info).check_machine(value)
        return value

    @field_validator("image")
    @classmethod
    def _image(cls, value: str | None) -> str | None:
        if value is not None and not _IMAGE_REF.match(value):
            raise ValueError(f"{value!r} is not an image reference like 'ros:noetic-ros-core' or 'ghcr.io/org/app:1.0'")
        return value

    @field_validator("env")
    @classmethod
    def _env(cls, value: dict[str, str]) -> dict[str, str]:
        for key in value:
            if not _ENV_NAME.match(key):
                raise ValueError(f"{key!r} is not an environment variable name")
        return value

    @model_validator(mode="after")
    def _one_kind(self, info: ValidationInfo | None = None) -> Node:
        given = [k for k in ("image", "build", "launch", "workload") if getattr(self, k) is not None]
        if not given and self.command:
            given = ["command"]
        if len(given) != 1:
            what = "none" if not given else " and ".join(given)
            raise FieldProblem(f"needs exactly one of image, build, launch, workload or command (got {what})")
        if self.command and given[0] in ("launch", "workload"):
            raise FieldProblem("command is for image nodes, or alone", field="command")
        named = self.machine if isinstance(self.machine, str) else self.machine.type
        if self.gpu and named is not None:
            _sizing(info).check_gpu(named)
        return self

    def machine_choice(self, region: str, *, spot: bool = False, provider: str | None = None) -> Choice:
        """The machine type this node runs on in ``region``: the named one, or the cheapest that fits
        (at the spot estimate when ``spot``: the target buys the node's machine as spot), as
        ``provider``'s ``cloud:`` variant (default: the default provider's) chooses."""
        named = self.machine if isinstance(self.machine, str) else self.machine.type
        need = self.machine.requirement(gpu=self.gpu) if isinstance(self.machine, Machine) and named is None else None
        return variant(provider).choose(named, need, region, spot=spot)

    @property
    def needs_gpu(self) -> bool:
        """``gpu: true``, or a machine requirement that asks for one."""
        return self.gpu or (isinstance(self.machine, Machine) and self.machine.gpu not in (None, False))

    @property
    def kind(self) -> NodeKind:
        if self.image or self.build:
            return "image"
        return "launch" if self.launch else "workload" if self.workload else "command"


class Relay(_Model):
    topics: Literal["auto"] | tuple[Topic, ...] = Field(
        default="auto", description="auto: relay whatever has a publisher on one side and a subscriber on the other."
    )
    compression: Compression | dict[Topic, Compression] = Field(
        default="none", description="One algorithm for all topics, or per topic."
    )
    queue_size: int = Field(default=2, ge=1, le=1000, description="Per-topic queue; the oldest message is dropped.")

    @field_validator("topics")
    @classmethod
    def _topics(cls, value: object) -> object:
        return tuple(_topic(t) for t in value) if isinstance(value, tuple) else value

    @field_validator("compression")
    @classmethod
    def _per_topic(cls, value: object) -> object:
        if isinstance(value, dict):
            for topic in value:
                _topic(topic)
        return value


class Manifest(_Model):
    """A fogiac deployment: which ROS nodes run off the robot, where, over which network."""

    name: DnsName = Field(description="DNS-safe deployment name; tags every cloud resource.")
    ros: Ros = Field(default_factory=Ros, description="ROS settings.")
    cloud: Cloud = Field(default_factory=Cloud, description="Where the cloud nodes run.")
    network: Network = Field(default_factory=Network, description="How the edge reaches them.")
    edge: Edge = Field(default_factory=Edge, description="The robot's side.")
    nodes: tuple[Node, ...] = Field(min_length=1, description="The nodes that run off the robot.")
    relay: Relay = Field(default_factory=Relay, description="How topics cross between edge and cloud.")
    tags: dict[str, str] = Field(default_factory=dict, description="Extra tags on every cloud resource.")
    _blocks: dict[str, BaseModel] = PrivateAttr(default_factory=dict)  # middleware name -> its block, validated

    @classmethod
    def owned_block(cls, key: str) -> type[BaseModel] | None:
        """The model of a top-level key an installed middleware owns (``beacon:``), or None."""
        if key in cls.model_fields:
            return None
        found: type[BaseModel] | None = registry.load("fogiac.middleware", "block_model")(key)
        return found

    def block(self, middleware: str) -> BaseModel | None:
        """The middleware's own block, as its model validated it; None when the manifest has none."""
        return self._blocks.get(middleware)

    @model_validator(mode="wrap")
    @classmethod
    def _middleware_blocks(cls, data: object, handler: ValidatorFunctionWrapHandler) -> Manifest:
        """A top-level key an installed middleware owns is validated by that middleware's model, with the
        rest of the manifest in the same run (every problem at once); any other unknown key stays refused
        by ``extra="forbid"``. The middlewares are asked only when the manifest has a key not fogiac's own."""
        if not isinstance(data, dict) or all(key in cls.model_fields for key in data):
            manifest: Manifest = handler(data)
            return manifest
        owned = {key: model for key in data if isinstance(key, str) and (model := cls.owned_block(key)) is not None}
        problems: list[InitErrorDetails] = []
        blocks: dict[str, BaseModel] = {}
        for key, model in owned.items():
            try:
                blocks[key] = model.model_validate(data[key])
            except ValidationError as err:
                problems += _moved(err, (key,))
        try:
            manifest = handler({key: value for key, value in data.items() if key not in owned})
        except ValidationError as err:
            problems = _moved(err, ()) + problems
        else:
            chosen = registry.load("fogiac.middleware", "for_distro")(manifest.ros.distro).name
            problems += [InitErrorDetails(type=PydanticCustomError("value_error", "{message}", {"message": (
                f"the {key} middleware's block, but ROS {manifest.ros.distro} crosses through {chosen}")}),
                loc=(key,), input=data[key]) for key in blocks if key != chosen]
        if problems:
            raise ValidationError.from_exception_data(cls.__name__, problems)
        manifest._blocks.update(blocks)
        return manifest

    @field_validator("tags")
    @classmethod
    def _tags(cls, value: dict[str, str]) -> dict[str, str]:
        for key in value:
            if key.startswith(("fogiac:", "aws:")):
                raise ValueError(f"tag {key!r} uses a reserved prefix (fogiac:, aws:)")
        return value

    @model_validator(mode="after")
    def _across(self) -> Manifest:
        names = [n.name for n in self.nodes]
        for i, name in enumerate(names):
            if name in names[:i]:
                raise FieldProblem(f"duplicate node name {name!r}", field=f"nodes[{i}].name")
        for i, node in enumerate(self.nodes):
            try:
                node.machine_choice(self.cloud.region, spot=node.spot, provider=self.cloud.chosen())
            except NoMachine as err:
                raise FieldProblem(str(err), field=f"nodes[{i}].machine") from None
        host_names = [h.name for h in self.cloud.hosts]
        for i, node in enumerate(self.nodes):
            if node.host is not None and node.host not in host_names:
                raise FieldProblem(
                    f"{node.host!r} is not in cloud.hosts", field=f"nodes[{i}].host", choices=tuple(host_names)
                )
        chosen = registry.load("fogiac.middleware", "for_distro")(self.ros.distro)
        for i, node in enumerate(self.nodes):
            if chosen.needs_listed_topics and node.topics == "auto":
                raise FieldProblem(
                    f"ROS {self.ros.distro} crosses through {chosen.name}, whose access control allows only listed "
                    "topics: give this node topics: {in: [...], out: [...]}",
                    field=f"nodes[{i}].topics",
                )
        return self


def _moved(err: ValidationError, prefix: tuple[str, ...]) -> list[InitErrorDetails]:
    """``err``'s problems, re-rooted under ``prefix``, to be raised again with others."""
    return [InitErrorDetails(type=e["type"], loc=prefix + tuple(e["loc"]), input=e["input"],
                             ctx=e.get("ctx", {})) for e in err.errors(include_url=False)]


def _resolve_paths(data: dict, base: Path) -> list[tuple[tuple, str]]:
    """Make file paths absolute against the manifest's folder; report missing ones."""
    missing: list[tuple[tuple, str]] = []

    def fix(container: dict, key: str, loc: tuple, *, folder: bool) -> None:
        value = container.get(key)
        if not isinstance(value, str) or any(ord(c) < 32 or ord(c) == 127 for c in value):
            return  # a control character is reported by the field's own check, on one line
        path = (base / value).resolve()
        container[key] = str(path)
        if not (path.is_dir() if folder else path.is_file()):
            missing.append((loc + (key,), f"{value!r} does not exist (looked for {path})"))
        elif key == "requirements":  # refused here already, not only when `up` reaches the host
            try:
                specifiers(path.read_text(errors="replace"), where=value)
            except RequirementsProblem as err:
                missing.append((loc + (key,), str(err)))
            except OSError as err:
                missing.append((loc + (key,), f"{value!r} cannot be read ({err.strerror})"))

    nodes = data.get("nodes")
    for i, node in enumerate(nodes if isinstance(nodes, list) else []):
        if isinstance(node, dict) and isinstance(node.get("launch"), dict):
            fix(node["launch"], "workspace", ("nodes", i, "launch"), folder=True)
            fix(node["launch"], "env_script", ("nodes", i, "launch"), folder=False)
            fix(node["launch"], "requirements", ("nodes", i, "launch"), folder=False)
        if isinstance(node, dict) and isinstance(node.get("build"), dict):
            fix(node["build"], "context", ("nodes", i, "build"), folder=True)
    cloud = data.get("cloud")
    if isinstance(cloud, dict):
        hosts = cloud.get("hosts")
        for i, host in enumerate(hosts if isinstance(hosts, list) else []):
            if isinstance(host, dict):
                fix(host, "key", ("cloud", "hosts", i), folder=False)
    return missing


def parse_manifest(text: str, *, source: str = "<manifest>", base: Path | None = None) -> Manifest:
    """Validate manifest text; ``base`` is the folder relative paths are taken from."""
    root, data = parse_yaml(text, source=source)
    lines = line_index(root)
    if not isinstance(data, dict):
        raise ManifestError([f"{source}:1: the manifest must be a mapping (name:, nodes:, ...)"])
    missing = _resolve_paths(data, base or Path.cwd())
    cloud = data.get("cloud")
    provider = cloud.get("provider") if isinstance(cloud, dict) else None
    try:  # the provider's variant names the nodes' machines (a broken provider: the default's)
        manifest = Manifest.model_validate(data, context={"provider": provider if known(provider) else None})
    except ValidationError as err:
        # Field errors and the rules across fields together: one run shows every problem.
        extra = missing + cross_field_problems(Manifest, data)
        raise ManifestError(
            format_errors(err, lines=lines, source=source, model=Manifest, extra=extra, data=data)
        ) from None
    if missing:
        raise ManifestError(format_errors(None, lines=lines, source=source, model=Manifest, extra=missing, data=data))
    return manifest


def load_manifest(path: str | Path) -> Manifest:
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ManifestError([f"{path}: no such file"]) from None
    except (OSError, UnicodeDecodeError) as err:
        raise ManifestError([f"{path}: cannot read: {err}"]) from None
    return parse_manifest(text, source=str(path), base=path.resolve().parent)


def json_schema() -> dict:
    schema = Manifest.model_json_schema(by_alias=True)
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "fogiac manifest"
    return schema


def node_types() -> tuple[type[BaseModel], ...]:
    """Every model of the manifest, for the README reference test."""
    return (Manifest, Ros, Cloud, Autostop, HostMachine, Network, Edge, Node, Machine, Launch, TopicLists, Relay)


__all__ = ["Manifest", "Node", "load_manifest", "parse_manifest", "json_schema"]
