"""FogROS2 compatibility: read a FogROS2 Python launch file into a fogiac manifest, never running it.

A FogROS2 launch file is Python: ``generate_launch_description`` builds a ``FogROSLaunchDescription``,
machines ``AWS(region=..., ec2_instance_type=..., disk_size=...)`` (``machine.add_docker_container
("docker run ... IMAGE CMD")`` adds a container to one) and nodes ``CloudNode(package=...,
executable=..., machine=...)`` beside plain ``Node(...)`` ones that stay on the robot. Running that
file would run whatever else it holds, so it is parsed with :mod:`ast` and read as data: only string
and number literals (and names bound to them) are taken; any other statement fogiac does not know
is one error line naming ``file:line``. Nothing here imports or executes the file.

What maps how: each container becomes an image node on its machine's instance type; each
``CloudNode`` becomes an image node running ``ros2 run PACKAGE EXECUTABLE`` in the distro's ROS
image (FogROS2 pushed the robot's workspace; fogiac runs containers, so the header says to build
an image holding the package). ROS 2 topics cross only when listed (Zenoh's access control), and a
FogROS2 file names none, so every node gets empty lists and the header says to fill them in.
"""

from __future__ import annotations

import ast
import shlex
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from fogiac.errors import ManifestError
from fogiac.manifest.clouds import variant
from fogiac.manifest.fogros import _dns
from fogiac.manifest.importers import Converted
from fogiac.manifest.schema import parse_manifest

SUFFIXES = (".py",)
DISTRO = "humble"  # the ROS 2 distribution FogROS2 supports
_ENTRY = "generate_launch_description"
_AWS_IGNORED = {"ami_image", "ros_workspace", "working_dir_base", "launch_foxglove"}  # fogiac chooses these itself
_NODE_IGNORED = {"output", "emulate_tty"}
# docker run options that take a value (the next word, or after "="); every other option is a flag.
_VALUED = {"-e", "--env", "-v", "--volume", "--net", "--network", "--name", "--gpus", "-p", "--publish", "-w",
           "--workdir", "--entrypoint", "--runtime", "--ipc", "--shm-size", "-u", "--user", "--env-file",
           "--mount", "--device", "--add-host", "--hostname", "-h", "--restart", "--pid", "--ulimit", "-m",
           "--memory", "--cpus", "--label", "-l"}
_FAILED = object()  # a name whose value could not be read (already reported)
_DDS_ENV = {"RMW_IMPLEMENTATION", "CYCLONEDDS_URI", "FASTRTPS_DEFAULT_PROFILES_FILE"}  # fogiac's Zenoh replaces DDS


@dataclass
class _Machine:
    line: int
    region: str
    instance_type: str
    disk_gb: int | None
    containers: list[tuple[str, int]] = field(default_factory=list)


@dataclass(frozen=True)
class _CloudNode:
    package: str
    executable: str
    name: str | None
    machine: _Machine
    line: int


class _Reader:
    """Walks the module and ``generate_launch_description`` statement by statement, collecting problems."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.problems: list[str] = []
        self.values: dict[str, Any] = {}  # name -> literal, _Machine, _CloudNode, "ld" or ("local", text)
        self.machines: list[_Machine] = []
        self.cloud: list[_CloudNode] = []
        self.local: list[str] = []
        self.found_entry = False

    def problem(self, node: ast.AST, what: str) -> None:
        self.problems.append(f"{self.source}:{getattr(node, 'lineno', 1)}: {what}")

    def unsupported(self, node: ast.AST) -> None:
        text = ast.unparse(node).splitlines()[0]
        self.problem(node, f"fogiac cannot import {text[:70]!r} (not a FogROS2 construct it knows)")

    def module(self, tree: ast.Module) -> None:
        for stmt in tree.body:
            if isinstance(stmt, ast.FunctionDef) and stmt.name == _ENTRY:
                self.found_entry = True
                for inner in stmt.body:
                    self.statement(inner)
            elif isinstance(stmt, (ast.Import, ast.ImportFrom, ast.FunctionDef)) or _is_docstring(stmt):
                continue  # helpers are never called; what they would compute is not read
            elif isinstance(stmt, ast.Assign):
                self.assign(stmt)
            else:
                self.unsupported(stmt)

    def statement(self, stmt: ast.stmt) -> None:
        if _is_docstring(stmt) or isinstance(stmt, ast.Return):
            return
        if isinstance(stmt, ast.Assign):
            self.assign(stmt)
        elif isinstance(stmt, ast.Expr) and isinstance(stmt.value, ast.Call):
            self.method(stmt.value)
        else:
            self.unsupported(stmt)

    def assign(self, stmt: ast.Assign) -> None:
        if len(stmt.targets) != 1 or not isinstance(stmt.targets[0], ast.Name):
            return self.unsupported(stmt)
        name = stmt.targets[0].id
        value = self.call(stmt.value) if isinstance(stmt.value, ast.Call) else self.literal(stmt.value)
        self.values[name] = _FAILED if value is None else value  # a failure is reported once, where it happened

    def literal(self, node: ast.expr) -> Any:
        try:
            return ast.literal_eval(node)
        except ValueError:
            self.unsupported(node)
            return None

    def call(self, call: ast.Call) -> Any:
        callee = _callee(call)
        if callee == "FogROSLaunchDescription":
            return "ld"
        if callee == "AWS":
            return self.aws(call)
        if callee == "CloudNode":
            return self.cloud_node(call)
        if callee == "Node":
            kwargs = {k.arg: k.value for k in call.keywords if k.arg}
            parts = [self.string(kwargs[k], k, quiet=True) or "?" for k in ("package", "executable") if k in kwargs]
            self.local.append("/".join(parts) or "?")
            return ("local", "/".join(parts))
        self.unsupported(call)
        return None

    def method(self, call: ast.Call) -> None:
        func = call.func
        if not (isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name)):
            return self.unsupported(call)
        owner = self.values.get(func.value.id)
        if owner is _FAILED or (func.attr == "add_action" and self.values.get(_name(call.args[:1])) is _FAILED):
            return None
        if owner == "ld" and func.attr == "add_action" and len(call.args) == 1:
            if isinstance(call.args[0], ast.Call):
                self.call(call.args[0])
            elif not (isinstance(call.args[0], ast.Name) and call.args[0].id in self.values):
                self.unsupported(call)
        elif isinstance(owner, _Machine) and func.attr == "add_docker_container" and len(call.args) == 1:
            command = self.string(call.args[0], "add_docker_container's command")
            if command is not None:
                owner.containers.append((command, call.lineno))
        else:
            self.unsupported(call)

    def string(self, node: ast.expr, what: str, *, quiet: bool = False) -> str | None:
        value = self.values.get(node.id) if isinstance(node, ast.Name) else getattr(node, "value", None)
        if isinstance(node, (ast.Name, ast.Constant)) and isinstance(value, str):
            return value
        if not quiet:
            self.problem(node, f"{what} must be a string literal (or a name bound to one)")
        return None

    def aws(self, call: ast.Call) -> _Machine | None:
        kwargs = {k.arg: k.value for k in call.keywords if k.arg}
        for key in sorted(set(kwargs) - {"region", "ec2_instance_type", "disk_size"} - _AWS_IGNORED):
            self.problem(kwargs[key], f"AWS argument {key!r} is not imported")
        if call.args or any(k.arg is None for k in call.keywords):
            self.problem(call, "AWS(...) takes keyword arguments only")
        region = self.string(kwargs["region"], "AWS region") if "region" in kwargs else "us-west-1"
        kind = self.string(kwargs["ec2_instance_type"], "ec2_instance_type") if "ec2_instance_type" in kwargs \
            else "t2.micro"  # FogROS2's defaults
        disk = self.literal(kwargs["disk_size"]) if "disk_size" in kwargs else None
        if region is None or kind is None:
            return None
        aws = variant("aws")  # FogROS2's AWS(...) names EC2 types and regions
        if aws.machine(kind) is None:
            self.problem(kwargs.get("ec2_instance_type", call),
                         f"ec2_instance_type {kind!r} is not in fogiac's catalog; e.g. t3.medium, c5.xlarge, "
                         "g4dn.xlarge")
        regions = sorted(aws.regions())
        if region not in regions:
            self.problem(kwargs.get("region", call),
                         f"region {region!r} is not one fogiac prices; valid: {', '.join(regions)}")
        machine = _Machine(call.lineno, region, kind, disk if isinstance(disk, int) else None)
        self.machines.append(machine)
        return machine

    def cloud_node(self, call: ast.Call) -> _CloudNode | None:
        kwargs = {k.arg: k.value for k in call.keywords if k.arg}
        for key in sorted(set(kwargs) - {"package", "executable", "machine", "name"} - _NODE_IGNORED):
            self.problem(kwargs[key], f"CloudNode argument {key!r} is not imported; set it in the node's image")
        missing = [k for k in ("package", "executable", "machine") if k not in kwargs]
        if call.args or missing:
            self.problem(call, f"CloudNode needs keyword arguments package, executable and machine (missing: "
                               f"{', '.join(missing) or 'none; positional ones are not read'})")
            return None
        package, executable = self.string(kwargs["package"], "package"), self.string(kwargs["executable"], "executable")
        name = self.string(kwargs["name"], "name") if "name" in kwargs else None
        where = kwargs["machine"]
        machine = self.aws(where) if isinstance(where, ast.Call) and _callee(where) == "AWS" else \
            self.values.get(where.id) if isinstance(where, ast.Name) else None
        if not isinstance(machine, _Machine):
            self.problem(where, "machine must be an AWS(...) machine (FogROS2's other clouds are not imported)")
            return None
        if package is None or executable is None:
            return None
        node = _CloudNode(package, executable, name, machine, call.lineno)
        self.cloud.append(node)
        return node


def _name(nodes: list[ast.expr]) -> str:
    return nodes[0].id if nodes and isinstance(nodes[0], ast.Name) else ""


def _callee(call: ast.Call) -> str:
    func = call.func
    return func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else ""


def _is_docstring(stmt: ast.stmt) -> bool:
    return isinstance(stmt, ast.Expr) and isinstance(stmt.value, ast.Constant) and isinstance(stmt.value.value, str)


def docker_node(command: str) -> tuple[str, tuple[str, ...], dict[str, str], bool] | None:
    """``docker run`` words -> (image, command after it, environment, wants GPUs); None if not a docker run."""
    words = shlex.split(command)
    words = words[1:] if words[:1] == ["sudo"] else words
    if words[:2] != ["docker", "run"]:
        return None
    env: dict[str, str] = {}
    gpus, i = False, 2
    while i < len(words) and words[i].startswith("-"):
        option, eq, value = words[i].partition("=")
        i += 1
        if not eq and option in _VALUED and i < len(words):
            value, i = words[i], i + 1
        if option in ("-e", "--env") and "=" in value and value.split("=", 1)[0] not in _DDS_ENV:
            key, val = value.split("=", 1)
            env[key] = val
        gpus = gpus or option == "--gpus"
    if i >= len(words):
        return None
    return words[i], tuple(words[i + 1:]), env, gpus


def convert(path: Path) -> tuple[dict, list[str], list[str]]:
    """The manifest's data, the nodes kept on the robot, and notes for the header; or ManifestError."""
    source = str(path)
    try:
        tree = ast.parse(path.read_text(), filename=source)
    except OSError as err:
        raise ManifestError([f"{source}: cannot read: {err.strerror}"]) from None
    except SyntaxError as err:
        raise ManifestError([f"{source}:{err.lineno or 1}: not valid Python: {err.msg}"]) from None
    reader = _Reader(source)
    reader.module(tree)
    if not reader.found_entry:
        reader.problems.append(f"{source}:1: no {_ENTRY}() here: not a ROS 2 launch file")
    regions = sorted({m.region for m in reader.machines})
    if len(regions) > 1:
        reader.problems.append(f"{source}:{reader.machines[-1].line}: machines in several regions "
                               f"({', '.join(regions)}); a fogiac manifest has one")
    if reader.problems:
        raise ManifestError(reader.problems)
    nodes, notes = _nodes(reader)
    if not nodes:
        raise ManifestError([f"{source}:1: no CloudNode and no add_docker_container in this launch file"])
    data = {"name": _dns(path.name.removesuffix(".py").removesuffix(".launch")), "ros": {"distro": DISTRO},
            "cloud": {"provider": "aws", "region": regions[0]}, "nodes": nodes}
    return data, reader.local, notes


def _nodes(reader: _Reader) -> tuple[list[dict], list[str]]:
    nodes: list[dict] = []
    notes: list[str] = []
    taken: set[str] = set()

    def unique(name: str) -> str:
        base, n = _dns(name), 2
        name = base
        while name in taken:
            name, n = f"{base}-{n}", n + 1
        taken.add(name)
        return name

    def node(name: str, machine: _Machine, image: str, command: tuple[str, ...], **extra: Any) -> None:
        entry: dict[str, Any] = {"name": unique(name), "machine": machine.instance_type, "image": image}
        if command:
            entry["command"] = list(command)
        entry.update(extra)
        if machine.disk_gb:
            entry["disk_gb"] = max(8, machine.disk_gb)
        entry["topics"] = {"in": [], "out": []}
        nodes.append(entry)

    for cloud in reader.cloud:
        image = f"ros:{DISTRO}-ros-base"
        node(cloud.name or cloud.executable, cloud.machine, image, ("ros2", "run", cloud.package, cloud.executable))
        notes.append(f"{nodes[-1]['name']}: FogROS2 pushed the robot's workspace; build an image FROM {image} "
                     f"holding package {cloud.package} and put it in image:")
    for machine in reader.machines:
        for command, line in machine.containers:
            parsed = docker_node(command)
            if parsed is None:
                raise ManifestError([f"{reader.source}:{line}: add_docker_container needs a 'docker run ... IMAGE' "
                                     "command"])
            image, args, env, gpus = parsed
            extra: dict[str, Any] = ({"env": env} if env else {}) | ({"gpu": True} if gpus else {})
            node(image.rsplit("/", 1)[-1].split(":")[0], machine, image, args, **extra)
            if "-v" in command or "--volume" in command:
                notes.append(f"{nodes[-1]['name']}: the container's volumes (-v) name paths on FogROS2's machine; "
                             "not carried over")
    return nodes, notes


def to_yaml(data: dict, *, source: Path, local: list[str], notes: list[str]) -> str:
    header = [f"# Imported from {source.name} (FogROS2) by `fogiac import`: read as text, never run.",
              "# Kept on the robot (not deployed by fogiac):"]
    header += [f"#   - {n}" for n in local] or ["#   (none)"]
    header += ["# To do before `fogiac up`:",
               "#   - list each node's topics (in: robot -> cloud, out: cloud -> robot); ROS 2 topics cross",
               "#     Zenoh's access control only when listed, and a FogROS2 launch file names none",
               f"#   - ros.distro is FogROS2's ({DISTRO}); set the robot's"]
    header += [f"#   - {n}" for n in notes]
    return "\n".join(header) + "\n" + yaml.safe_dump(data, sort_keys=False)


def import_launch(path: Path, *, out: Path | None = None) -> Converted:
    """Read, convert and validate; the manifest and its YAML text. Nothing is written here."""
    data, local, notes = convert(path)
    text = to_yaml(data, source=path, local=local, notes=notes)
    manifest = parse_manifest(text, source=str(out or path), base=(out or path).resolve().parent)
    return Converted(manifest, text, ())  # its notes are in the YAML's header, for the user to act on
