"""A manifest node and what it runs: an image, a launch file, a workload or a command, on a named
machine type or on what it needs (``machine: {gpu: T4, vcpus: '>=8'}``)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import (
    Discriminator,
    Field,
    StrictInt,
    Tag,
    ValidationError,
    ValidationInfo,
    ValidatorFunctionWrapHandler,
    WrapValidator,
    field_validator,
    model_validator,
)

from fogiac import registry
from fogiac.manifest.clouds import variant
from fogiac.manifest.fields import (
    _ENV_NAME,
    _IMAGE_REF,
    DnsName,
    PlainPath,
    Secret,
    Topic,
    _Model,
    _sizing,
    _topic,
)
from fogiac.manifest.machines import Choice, Requirement, parse_bound
from fogiac.manifest.problems import FieldProblem
from fogiac.manifest.replicas import (
    DEFAULT_MATCH,
    MAX_REPLICAS,
    Hedge,
    check_match,
    check_type,
    match_problems,
    unchecked,
)


class Launch(_Model):
    package: str = Field(description="ROS package holding the launch file.")
    file: str = Field(description="Launch file name, e.g. planner.launch.")
    workspace: PlainPath = Field(description="Workspace folder to push, relative to the manifest.")
    env_script: PlainPath | None = Field(default=None, description="Script run once per change to set the host up.")
    requirements: PlainPath | None = Field(
        default=None, description="pip requirements file of the package's Python nodes, relative to the manifest: "
        "installed in the host's virtual environment (native) or in the node's image (container).")


def _env_kind(value: object) -> str:
    return "secret" if isinstance(value, (dict, Secret)) else "value"


# A plain value, or {secret: ...}: a mapping is read as a secret only, so its problem is named as one.
EnvValue = Annotated[Annotated[str, Tag("value")] | Annotated[Secret, Tag("secret")], Discriminator(_env_kind)]


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


_NEEDS = ("gpu", "vcpus", "memory_gib", "arch", "gpu_memory_gib")  # what a requirement may name


class Machine(_Model):
    """What a node needs instead of a type name: compile picks the cheapest catalogue type that fits."""

    type: str | None = Field(default=None, description="A type from the target's catalogue; or leave it out.")
    gpu: bool | str | None = Field(default=None, description="true (any GPU) or a model such as T4, A10G, V100.")
    vcpus: StrictInt | str | None = Field(default=None, description="vCPUs: a number (at least) or a bound like '>=8'.")
    memory_gib: float | str | None = Field(default=None, description="Memory in GiB: a number (at least) or '>=16'.")
    arch: Literal["x86_64", "arm64"] | None = Field(default=None, description="CPU architecture (arm64: Graviton).")
    gpu_memory_gib: float | str | None = Field(default=None,
                                               description="GPU memory in GiB, all GPUs together, e.g. '>=24'.")

    @field_validator("vcpus", "memory_gib", "gpu_memory_gib")
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
        needs = [k for k in _NEEDS if getattr(self, k) is not None]
        if self.type is not None and needs:
            raise FieldProblem(f"give either type or requirements ({', '.join(needs)}), not both")
        if self.type is None and not needs:
            raise FieldProblem(f"needs a type or at least one of {', '.join(_NEEDS)}")
        return self

    def requirement(self, *, gpu: bool = False) -> Requirement:
        """The requirement; ``gpu`` (the node's own flag) asks for any GPU when none is named."""
        return Requirement(
            gpu=self.gpu if self.gpu not in (None, False) else (True if gpu else None),
            vcpus=parse_bound(self.vcpus) if self.vcpus is not None else None,
            memory_gib=parse_bound(self.memory_gib) if self.memory_gib is not None else None,
            arch=self.arch,
            gpu_memory_gib=parse_bound(self.gpu_memory_gib) if self.gpu_memory_gib is not None else None,
        )


def _installed(value: object, handler: ValidatorFunctionWrapHandler) -> object:
    """A workload another installed package declares (entry point group ``fogiac.workloads``); the
    distributions are read only for a name that is not fogiac's own, so ``validate`` stays fast."""
    try:
        return handler(value)
    except ValidationError:
        if isinstance(value, str) and registry.known("fogiac.workloads", value):
            return value
        raise


if TYPE_CHECKING:
    Workload = str
else:  # the workloads fogiac ships (what the schema and reference list), and (_installed) another package's
    Workload = Annotated[Literal[registry.names("fogiac.workloads", own=True)], WrapValidator(_installed)]


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
    workload: Workload | None = Field(default=None, description="A workload that ships with fogiac, or one another "
                                              "installed package declares (entry point group fogiac.workloads).")
    command: tuple[str, ...] = Field(
        default=(), description="Arguments after the image; alone: a command run as the node (in the ROS image "
        "on container hosts)."
    )
    gpu: bool = Field(default=False, description="The node needs a GPU.")
    topics: Literal["auto"] | TopicLists = Field(default="auto", description="Topics relayed for this node.")
    disk_gb: int = Field(default=30, strict=True, ge=8, le=16384,
                         description="Root volume size in GiB (gp3, encrypted).")
    spot: bool = Field(default=False, description="Use a spot instance.")
    env: dict[str, EnvValue] = Field(
        default_factory=dict, description="Environment variables for the node; a secret as {secret: env:NAME} "
        "or {secret: file:PATH}, read at `up` and never shown or recorded.")
    host: str | None = Field(default=None, description="For the hosts target: which cloud.hosts entry runs it.")
    replicas: int = Field(default=1, strict=True, ge=1, le=MAX_REPLICAS,
                          description="Copies of the node, each on a host of its own (aws: in different zones): "
                          "the robot gets the first reply to each request.")
    reply_match: str = Field(default=DEFAULT_MATCH, description="With replicas: the reply field that names its "
                             "request (a reply copies it from the request); header.stamp needs a std_msgs/Header.")
    hedge: Literal["all"] | Hedge = Field(default="all", description="With replicas: send each request to all at "
                                          "once, or {delay_ms: D} to the first and to the others after D ms.")
    message_types: dict[Topic, str] = Field(default_factory=dict, description="ROS message type of topics, e.g. "
                                            "{/plan: geometry_msgs/PoseArray}: validate checks reply_match with it.")
    serve: Literal["all", "per_robot"] | tuple[str, ...] = Field(
        default="all", description="Whom the node serves in a fleet (robots:): all (one instance every robot "
        "shares), per_robot (one instance per robot, in its namespace /<robot>, its listed topics remapped there; "
        "command nodes, ROS 1 and ROS 2), or a list of robot names.")
    replica_hosts: tuple[str, ...] = Field(default=(), description="For the hosts target: the cloud.hosts entries "
                                           "that carry the node's replicas, one each (default: the next ones).")

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
    def _env(cls, value: dict[str, EnvValue]) -> dict[str, str | Secret]:
        for key, text in value.items():
            if not _ENV_NAME.match(key):
                raise ValueError(f"{key!r} is not an environment variable name")
            # an env file holds one variable a line
            if isinstance(text, str) and not text.replace("\t", "").isprintable():
                raise ValueError(f"{key}: {text!r} holds a line break or control character; env values are one line")
        return value

    @field_validator("reply_match")
    @classmethod
    def _reply_match(cls, value: str) -> str:
        return check_match(value)

    @field_validator("message_types")
    @classmethod
    def _message_types(cls, value: dict[str, str]) -> dict[str, str]:
        for topic, name in value.items():
            _topic(topic)
            check_type(name)
        return value

    @model_validator(mode="after")
    def _replicated(self) -> Node:
        """A replicated node's replies are merged on its out topics: they must be listed, and matchable."""
        if self.replica_hosts and len(self.replica_hosts) != self.replicas:
            raise FieldProblem(f"names {len(self.replica_hosts)} hosts for replicas: {self.replicas}",
                               field="replica_hosts")
        if len(set(self.replica_hosts)) != len(self.replica_hosts):
            raise FieldProblem("names a host twice; each replica needs a host of its own", field="replica_hosts")
        if self.replicas == 1:
            return self
        if self.topics == "auto" or not self.topics.outputs:
            raise FieldProblem(f"replicas: {self.replicas} needs its out topics listed (topics: {{in: [...], out: "
                               "[...]}}): the edge merges the replicas' replies on them", field="topics")
        for message, field in match_problems(self.topics.outputs, self.message_types, self.reply_match):
            raise FieldProblem(message, field=field)
        return self

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

    def unchecked_match(self) -> str | None:
        """For a replicated node, the line naming out topics whose reply match validate could not check."""
        if self.replicas == 1 or self.topics == "auto":
            return None
        return unchecked(f"node {self.name}", self.topics.outputs, self.message_types, self.reply_match)

    @property
    def needs_gpu(self) -> bool:
        """``gpu: true``, or a machine requirement that asks for one."""
        return self.gpu or (isinstance(self.machine, Machine) and self.machine.gpu not in (None, False))

    @property
    def kind(self) -> NodeKind:
        if self.image or self.build:
            return "image"
        return "launch" if self.launch else "workload" if self.workload else "command"
