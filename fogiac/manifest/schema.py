"""The manifest (``fogiac.yaml``): typed, frozen, validated.

:func:`load_manifest` is the only code that sees raw YAML. Every problem it finds becomes one
line ``PATH:LINE: field.path: what is wrong`` (with a "did you mean" where one is close), all
of them at once, raised as :class:`~fogiac.errors.ManifestError`.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import (
    BaseModel,
    Field,
    PrivateAttr,
    ValidationError,
    ValidationInfo,
    ValidatorFunctionWrapHandler,
    field_validator,
    model_validator,
)
from pydantic_core import InitErrorDetails, PydanticCustomError

from fogiac import middlewares
from fogiac.errors import ManifestError, PlanError
from fogiac.manifest.blocks import Autostop, Cloud, Edge, HostMachine, Network, Registry, Relay, Robot, Ros
from fogiac.manifest.clouds import Limits, limits
from fogiac.manifest.crossfield import cross_field_problems
from fogiac.manifest.fields import DnsName, _Model, ssh_from_problem
from fogiac.manifest.machines import NoMachine
from fogiac.manifest.nodes import Build, Launch, Machine, Node, NodeKind, TopicLists, Workload
from fogiac.manifest.problems import FieldProblem, format_errors, parse_yaml, raise_all
from fogiac.manifest.replicas import Hedge
from fogiac.manifest.requirements import RequirementsProblem, specifiers
from fogiac.manifest.source import read_source

FOGIAC_TAGS = 4  # the tags fogiac sets on every resource: fogiac:stack, fogiac:manifest, fogiac:node, Name
RESERVED_TAGS = ("fogiac:",)  # fogiac's own tag prefix; the cloud's variant names its own (Limits.reserved)


class State(_Model):
    """Where this manifest's stack records are kept when a lab shares them (``fogiac state``)."""

    url: str = Field(pattern=r"^s3://[a-z0-9][a-z0-9.-]{1,61}[a-z0-9](/[^?#]*)?$",
                     description="The shared state store, s3://BUCKET/PREFIX; FOGIAC_STATE_URL wins over it.")
    kms_key: str | None = Field(default=None, description="The KMS key (id, ARN or alias) that encrypts the "
                                "stack's keys and certificates in the store.")


class Manifest(_Model):
    """A fogiac deployment: which ROS nodes run off the robot, where, over which network."""

    name: DnsName = Field(description="DNS-safe deployment name; tags every cloud resource.")
    ros: Ros = Field(default_factory=Ros, description="ROS settings.")
    cloud: Cloud = Field(default_factory=Cloud, description="Where the cloud nodes run.")
    network: Network = Field(default_factory=Network, description="How the edge reaches them.")
    edge: Edge = Field(default_factory=Edge, description="The robot's side (one robot: the shorthand of robots:).")
    robots: tuple[Robot, ...] = Field(default=(), min_length=1, description="A fleet: every robot, each with its "
                                      "name, its ROS master and its own certificate; instead of edge:.")
    nodes: tuple[Node, ...] = Field(min_length=1, description="The nodes that run off the robot.")
    relay: Relay = Field(default_factory=Relay, description="How topics cross between edge and cloud.")
    tags: dict[str, str] = Field(default_factory=dict, description="Extra tags on every cloud resource.")
    state: State | None = Field(default=None, description="Share the stack's records with the lab: where, "
                                "and the key that encrypts its secrets (default: the local state folder).")
    allow_paths_outside: bool = Field(
        default=False, description="Let a workspace, env_script, requirements or build context resolve outside "
        "the manifest's folder (through ../ or a symbolic link): up pushes it to the hosts.")
    _blocks: dict[str, BaseModel] = PrivateAttr(default_factory=dict)  # middleware name -> its block, validated

    @classmethod
    def owned_block(cls, key: str) -> type[BaseModel] | None:
        """The model of a top-level key an installed middleware owns (``beacon:``), or None."""
        if key in cls.model_fields:
            return None
        found: type[BaseModel] | None = middlewares.block_model(key)
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
            chosen = middlewares.for_distro(manifest.ros.distro).name
            problems += [InitErrorDetails(type=PydanticCustomError("value_error", "{message}", {"message": (
                f"the {key} middleware's block, but ROS {manifest.ros.distro} crosses through {chosen}")}),
                loc=(key,), input=data[key]) for key in blocks if key != chosen]
        if problems:
            raise ValidationError.from_exception_data(cls.__name__, problems)
        manifest._blocks.update(blocks)
        return manifest

    @field_validator("nodes", mode="before")
    @classmethod
    def _not_too_many(cls, value: object, info: ValidationInfo) -> object:
        most = _limits(info).nodes  # the provider's cap (aws: what its hosts subnet holds)
        if most is not None and isinstance(value, (list, tuple)) and len(value) > most:  # before any node is validated
            raise ValueError(f"{len(value)} nodes; a stack holds at most {most}: split them into several "
                             "manifests (or environments)")
        return value

    @field_validator("name")
    @classmethod
    def _single_dashes(cls, value: str) -> str:
        if "--" in value:  # '--' joins a name and an environment that holds a '-' into the stack's name
            raise ValueError(f"{value!r} holds '--', which fogiac keeps for joining the name and the environment")
        return value

    @field_validator("tags")
    @classmethod
    def _tags(cls, value: dict[str, str], info: ValidationInfo) -> dict[str, str]:
        cloud = _limits(info)  # the provider's limits, found at validate rather than at up
        reserved = RESERVED_TAGS + cloud.reserved
        for key in value:
            if key.startswith(reserved):
                raise ValueError(f"tag {key!r} uses a reserved prefix ({', '.join(reserved)})")
        if cloud.tags is not None and len(value) > cloud.tags - FOGIAC_TAGS:  # fogiac's own take FOGIAC_TAGS
            raise ValueError(f"{len(value)} tags; a cloud resource holds {cloud.tags} and fogiac sets {FOGIAC_TAGS} "
                             f"(fogiac:stack, fogiac:manifest, fogiac:node, Name): at most {cloud.tags - FOGIAC_TAGS}")
        for key, text in value.items():
            if cloud.tag_key is not None and len(key) > cloud.tag_key:
                raise ValueError(f"tag key {key[:20]!r}... is {len(key)} characters; the limit is {cloud.tag_key}")
            if cloud.tag_value is not None and len(text) > cloud.tag_value:
                raise ValueError(f"tag {key!r}: its value is {len(text)} characters; the limit is {cloud.tag_value}")
        return value

    @model_validator(mode="after")
    def _across(self) -> Manifest:
        problems: list[FieldProblem] = []  # every one, each by its path: validate reports in one run
        names = [n.name for n in self.nodes]
        for i, name in enumerate(names):
            if name in names[:i]:
                problems.append(FieldProblem(f"duplicate node name {name!r}", field=f"nodes[{i}].name"))
        for i, node in enumerate(self.nodes):
            try:
                node.machine_choice(self.cloud.region, spot=node.spot, provider=self.cloud.chosen())
            except NoMachine as err:
                problems.append(FieldProblem(str(err), field=f"nodes[{i}].machine"))
        host_names = [h.name for h in self.cloud.hosts]
        for i, node in enumerate(self.nodes):
            if node.host is not None and node.host not in host_names:
                problems.append(FieldProblem(
                    f"{node.host!r} is not in cloud.hosts", field=f"nodes[{i}].host", choices=tuple(host_names)
                ))
            for name in node.replica_hosts:
                if name not in host_names:
                    problems.append(FieldProblem(f"{name!r} is not in cloud.hosts", field=f"nodes[{i}].replica_hosts",
                                                 choices=tuple(host_names)))
            if node.host is not None and node.replica_hosts:
                problems.append(FieldProblem("give host or replica_hosts, not both", field=f"nodes[{i}].replica_hosts"))
        problems += fleet_problems(self)
        chosen = middlewares.for_distro(self.ros.distro)
        for message, field in chosen.manifest_problems(self):  # the middleware's own rules, in its words
            problems.append(FieldProblem(message, field=field))
        raise_all(problems)
        return self


def fleet_problems(manifest: Manifest) -> list[FieldProblem]:
    """The fleet's rules: ``robots:`` or ``edge:``, names and masters unique, and whom each node serves."""
    problems: list[FieldProblem] = []
    names = [r.name for r in manifest.robots]
    if manifest.robots and "edge" in manifest.model_fields_set:
        problems.append(FieldProblem("give edge: (one robot) or robots: (a fleet), not both", field="robots"))
    # each robot's side where its middleware reaches it: its ROS master (ROS 1), its edge router (ROS 2)
    entry = getattr(middlewares.for_distro(manifest.ros.distro), "edge_entry", None) if manifest.robots else None
    for i, robot in enumerate(manifest.robots):
        reached = entry(robot) if entry is not None else robot.ros_master
        if robot.name in names[:i]:
            problems.append(FieldProblem(f"duplicate robot name {robot.name!r}", field=f"robots[{i}].name"))
        elif reached in [entry(r) if entry is not None else r.ros_master for r in manifest.robots[:i]]:
            field, what = ("ros_master", "master") if reached == robot.ros_master else ("zenoh_router", "edge router")
            problems.append(FieldProblem(f"{reached!r} is another robot's {what} too", field=f"robots[{i}].{field}"))
    for i, node in enumerate(manifest.nodes):
        if node.serve == "all":
            continue
        if not manifest.robots:
            problems.append(FieldProblem(f"serve: {_said(node.serve)} needs a robots: list", field=f"nodes[{i}].serve"))
        elif node.serve == "per_robot":
            problems += [FieldProblem(message, field=f"nodes[{i}].{field}")
                         for message, field in _per_robot_problems(manifest, node)]
        else:
            for name in node.serve:
                if name not in names:
                    problems.append(FieldProblem(f"{name!r} is not in robots", field=f"nodes[{i}].serve",
                                                 choices=tuple(names)))
            if not node.serve:
                problems.append(FieldProblem("serves no robot: give all or at least one robot's name",
                                             field=f"nodes[{i}].serve"))
    return problems


def _per_robot_problems(manifest: Manifest, node: Node) -> list[tuple[str, str]]:
    """What ``serve: per_robot`` (one instance per robot, each in its namespace) needs today: a ROS generation
    whose nodes take a namespace and remaps as arguments (ROS 1's ``__ns:=``, ROS 2's ``--ros-args -r``), a
    command node to give them to, and listed topics to remap (a topic left out would be one topic every
    instance shares)."""
    try:
        chosen = middlewares.for_distro(manifest.ros.distro)
    except PlanError:
        return []  # the unknown distribution is reported by its own field
    # Its Launching (fogiac.hostmodel) says how; a middleware plug-in without one runs no per-robot instances.
    if getattr(getattr(chosen, "launching", None), "instance_args", None) is None:
        return [(f"serve: per_robot (one instance per robot) needs a middleware that puts a node in a robot's "
                 f"namespace; ROS {manifest.ros.distro} crosses through {chosen.name}, which has no per-robot "
                 "instances yet: give all or a list of robots", "serve")]
    problems = []
    if node.kind != "command":
        problems.append((f"serve: per_robot runs a command: node (each instance takes its robot's namespace as "
                         f"ROS arguments); a {node.kind} node cannot yet: give all or a list of robots", "serve"))
    if node.topics == "auto":
        problems.append(("serve: per_robot needs the node's topics listed (topics: {in: [...], out: [...]}): each "
                         "instance's are remapped into its robot's namespace", "topics"))
    if node.replicas > 1:
        problems.append((f"serve: per_robot with replicas: {node.replicas} is not built: give one or the other",
                         "replicas"))
    if node.topics != "auto":
        # Each instance's topics are remapped to /<robot><topic>: one already under a robot would become
        # /arm2/arm1/scan for arm2's instance, a topic no robot publishes or reads.
        robots = {robot.name for robot in manifest.robots}
        for side, listed in (("in", node.topics.inputs), ("out", node.topics.outputs)):
            for topic in listed:
                owner = topic.split("/")[1] if topic.count("/") > 1 else None
                if owner in robots:
                    bare = topic[len(owner) + 1:]
                    problems.append((f"{topic!r} is inside robot {owner}'s namespace; serve: per_robot puts each "
                                     f"instance's topics under its robot (/<robot>{bare}): list it as {bare!r}",
                                     f"topics.{side}"))
    return problems


def _said(value: object) -> str:
    return value if isinstance(value, str) else "[" + ", ".join(map(str, value)) + "]"  # type: ignore[call-overload]


def _limits(info: ValidationInfo) -> Limits:
    """What the manifest's provider allows (the validation context names it; without one: the default's)."""
    context = info.context if isinstance(info.context, dict) else {}
    return limits(context.get("provider"))


def _moved(err: ValidationError, prefix: tuple[str, ...]) -> list[InitErrorDetails]:
    """``err``'s problems, re-rooted under ``prefix``, to be raised again with others."""
    return [InitErrorDetails(type=e["type"], loc=prefix + tuple(e["loc"]), input=e["input"],
                             ctx=e.get("ctx", {})) for e in err.errors(include_url=False)]


def _resolve_paths(data: dict, base: Path) -> list[tuple[tuple, str]]:
    """Make file paths absolute against the manifest's folder; report missing ones."""
    missing: list[tuple[tuple, str]] = []
    root = base.resolve()
    outside_ok = data.get("allow_paths_outside") is True

    def fix(container: dict, key: str, loc: tuple, *, folder: bool, pushed: bool = True) -> None:
        value = container.get(key)
        if not isinstance(value, str) or any(ord(c) < 32 or ord(c) == 127 for c in value):
            return  # a control character is reported by the field's own check, on one line
        path = (base / value).resolve()
        container[key] = str(path)
        if pushed and not outside_ok and not path.is_relative_to(root):
            # up pushes it to the hosts: ../../.. or a symbolic link must not carry ~/.aws or ~/.fogiac there
            missing.append((loc + (key,), f"{value!r} resolves to {path}, outside the manifest's folder {root}; "
                            "up would push it to the hosts (move it under the manifest's folder, or set "
                            "allow_paths_outside: true)"))
        elif not (path.is_dir() if folder else path.is_file()):
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
    refs = [node.get("env") for node in (nodes if isinstance(nodes, list) else []) if isinstance(node, dict)]
    if isinstance(cloud, dict) and isinstance(cloud.get("registries"), list):
        refs += [{"password": r.get("password")} for r in cloud["registries"] if isinstance(r, dict)]
    for values in refs:
        for value in values.values() if isinstance(values, dict) else ():
            ref = value.get("secret") if isinstance(value, dict) else None
            if isinstance(ref, str) and ref.startswith("file:") and not any(ord(c) < 32 for c in ref):
                # read at `up` on the operator's machine, wherever it is (not pushed): only made absolute
                value["secret"] = "file:" + str((base / Path(ref[5:]).expanduser()).resolve())
    if isinstance(cloud, dict):
        hosts = cloud.get("hosts")
        for i, host in enumerate(hosts if isinstance(hosts, list) else []):
            if isinstance(host, dict):
                fix(host, "key", ("cloud", "hosts", i), folder=False, pushed=False)  # read here, never pushed
    return missing


def parse_manifest(text: str, *, source: str = "<manifest>", base: Path | None = None) -> Manifest:
    """Validate manifest text; ``base`` is the folder relative paths are taken from."""
    data, lines = parse_yaml(text, source=source)
    if not isinstance(data, dict):
        raise ManifestError([f"{source}:1: the manifest must be a mapping (name:, nodes:, ...)"])
    missing = _resolve_paths(data, base or Path.cwd())
    cloud = data.get("cloud")
    provider = cloud.get("provider") if isinstance(cloud, dict) else None
    try:  # the provider's variant names the nodes' machines (a broken provider: the default's, clouds.sizing)
        manifest = Manifest.model_validate(data, context={"provider": provider})
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
    text = read_source(path)
    return parse_manifest(text, source=str(path), base=path.resolve().parent)


def json_schema() -> dict:
    schema = Manifest.model_json_schema(by_alias=True)
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "fogiac manifest"
    return schema


def node_types() -> tuple[type[BaseModel], ...]:
    """Every model of the manifest, for the README reference test."""
    return (Manifest, Ros, Cloud, Autostop, HostMachine, Registry, Network, Edge, Robot, Node, Machine, Launch,
            TopicLists, Relay, Hedge)



# What other modules import from here (the blocks and nodes live in blocks.py and nodes.py).
__all__ = ["Autostop", "Build", "Cloud", "Edge", "Hedge", "HostMachine", "Launch", "Machine", "Manifest", "Network",
           "Node", "NodeKind", "Registry", "Relay", "Robot", "Ros", "TopicLists", "Workload", "json_schema",
           "load_manifest",
           "parse_manifest", "ssh_from_problem"]
