"""FogROS2 compatibility: read a FogROS2 Python launch file into a fogiac manifest, never running it.

A FogROS2 launch file is Python: ``generate_launch_description`` builds a ``FogROSLaunchDescription``,
machines ``fogros2.AWSCloudInstance(region=..., ec2_instance_type=..., disk_size=...)`` (or the older
``AWS(...)``; ``machine.add_docker_container("docker run ... IMAGE CMD")`` adds a container to one)
and nodes ``CloudNode(package=..., executable=..., machine=...)`` beside plain ``Node(...)`` ones that
stay on the robot, added one by one or in a loop over names. FogROS2's launch-time helpers become
what fogiac decides offline: ``find_nearest_region_and_ami`` the listed region nearest this machine's
time zone, or the first listed when the zone says nothing of where it is
(:mod:`fogiac.manifest.fogros2_nearest`; a to-do line names the choice), ``find_cheapest_ec2_instance_type``
a machine requirement that ``plan`` resolves to the cheapest fit; ``ami_image=`` is dropped (fogiac picks
the image by architecture). Running that file would run whatever else it holds, so it is parsed with
:mod:`ast` and read as data: only string and number literals are taken, with names bound to them and the
file's own functions that do nothing but return one (FogROS2's examples list their regions so);
``print`` and logging calls are passed over (they change nothing deployed); any other statement fogiac
does not know is one error line naming ``file:line``. Nothing here imports or executes the file, and what
it says reaches the manifest only as quoted strings and one-line comments (:mod:`.fogros_yaml`).

What maps how: each container becomes an image node on its machine's instance type; each
``CloudNode`` becomes an image node running ``ros2 run PACKAGE EXECUTABLE`` in the distro's ROS
image (FogROS2 pushed the robot's workspace; fogiac runs containers, so the header says to build
an image holding the package). ROS 2 topics cross only when listed (Zenoh's access control), and a
FogROS2 file names none, so every node gets empty lists and the header says to fill them in.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fogiac.errors import ManifestError
from fogiac.manifest.clouds import variant
from fogiac.manifest.fogros import _dns
from fogiac.manifest.fogros2_docker import docker_node
from fogiac.manifest.fogros2_nearest import local_zone, nearest
from fogiac.manifest.fogros_yaml import FromLaunch, dump, validate
from fogiac.manifest.importers import Converted
from fogiac.manifest.problems import FieldProblem
from fogiac.manifest.source import read_source, screen_python

SUFFIXES = (".py",)
DISTRO = "humble"  # the ROS 2 distribution FogROS2 supports
_ENTRY = "generate_launch_description"
_AWS_IGNORED = {"ami_image", "ros_workspace", "working_dir_base", "launch_foxglove"}  # fogiac chooses these itself
_NODE_IGNORED = {"output", "emulate_tty"}
_FAILED = object()  # a name whose value could not be read (already reported)
_AMI = object()  # the AMI find_nearest_region_and_ami returns: fogiac picks its own image
_LOGGER = object()  # logging.getLogger(...): its calls change nothing deployed
_LOG_CALLS = {"debug", "info", "warning", "warn", "error", "critical", "exception", "log"}
_DESCRIPTIONS = ("FogROSLaunchDescription", "LaunchDescription")
_AWS = ("AWS", "AWSCloudInstance")
_OTHER_CLOUDS = {"GCP": "GCP", "GCPCloudInstance": "GCP", "KubeInstance": "Kubernetes", "Kubernetes": "Kubernetes"}


@dataclass
class _Machine:
    line: int
    region: str
    instance_type: str | dict[str, Any]  # a type, or a requirement (find_cheapest_ec2_instance_type)
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
        self.notes: list[str] = []
        self.found_entry = False
        # The file's own functions: the literal a function returns and nothing else does, or None.
        self.functions: dict[str, ast.expr | None] = {}

    def problem(self, node: ast.AST, what: str) -> None:
        self.problems.append(f"{self.source}:{getattr(node, 'lineno', 1)}: {what}")

    def unsupported(self, node: ast.AST) -> None:
        text = ast.unparse(node).splitlines()[0]
        self.problem(node, f"fogiac cannot import {text[:70]!r} (not a FogROS2 construct it knows)")

    def module(self, tree: ast.Module) -> None:
        self.functions = {stmt.name: _returned_literal(stmt) for stmt in tree.body
                          if isinstance(stmt, (ast.FunctionDef, ast.AsyncFunctionDef)) and stmt.name != _ENTRY}
        for stmt in tree.body:
            if isinstance(stmt, ast.FunctionDef) and stmt.name == _ENTRY:
                self.found_entry = True
                for inner in stmt.body:
                    self.statement(inner)
            elif isinstance(stmt, (ast.Import, ast.ImportFrom, ast.FunctionDef, ast.AsyncFunctionDef)) \
                    or _is_docstring(stmt) or self.no_effect(stmt):
                continue  # a helper is read only where it is called, and only if it returns a literal
            elif isinstance(stmt, ast.Assign):
                self.assign(stmt)
            else:
                self.unsupported(stmt)

    def no_effect(self, stmt: ast.stmt) -> bool:
        """``print(...)`` or a logging call whose arguments call nothing: it changes nothing deployed."""
        if not (isinstance(stmt, ast.Expr) and isinstance(stmt.value, ast.Call)):
            return False
        call, func = stmt.value, stmt.value.func
        logs = isinstance(func, ast.Attribute) and func.attr in _LOG_CALLS and isinstance(func.value, ast.Name) \
            and (func.value.id == "logging" or self.values.get(func.value.id) is _LOGGER)
        said = [*call.args, *(k.value for k in call.keywords)]
        return (logs or (isinstance(func, ast.Name) and func.id == "print")) \
            and not any(isinstance(n, ast.Call) for arg in said for n in ast.walk(arg))

    def statement(self, stmt: ast.stmt) -> None:
        if _is_docstring(stmt) or isinstance(stmt, ast.Return) or self.no_effect(stmt):
            return
        if isinstance(stmt, ast.Assign):
            self.assign(stmt)
        elif isinstance(stmt, ast.Expr) and isinstance(stmt.value, ast.Call):
            self.method(stmt.value)
        elif _is_loop_over_names(stmt):
            assert isinstance(stmt, ast.For) and isinstance(stmt.target, ast.Name)
            for item in stmt.iter.elts:  # type: ignore[attr-defined]
                self.values[stmt.target.id] = self.values.get(item.id, _FAILED)
                for inner in stmt.body:
                    self.statement(inner)
        else:
            self.unsupported(stmt)

    def assign(self, stmt: ast.Assign) -> None:
        if len(stmt.targets) == 1 and isinstance(stmt.value, ast.Call) \
                and _callee(stmt.value) == "find_nearest_region_and_ami":
            return self.nearest(stmt)
        if len(stmt.targets) != 1 or not isinstance(stmt.targets[0], ast.Name):
            return self.unsupported(stmt)
        name = stmt.targets[0].id
        value = self.call(stmt.value) if isinstance(stmt.value, ast.Call) else self.literal(stmt.value)
        self.values[name] = _FAILED if value is None else value  # a failure is reported once, where it happened

    def literal(self, node: ast.expr, *, quiet: bool = False) -> Any:
        """A literal, a name bound to one, or a call of this file's function that returns one; else None."""
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in self.functions:
            return self.own_call(node, quiet=quiet)
        if isinstance(node, ast.Name) and node.id in self.values:
            value = self.values[node.id]
            return None if value is _FAILED else value
        try:
            return ast.literal_eval(node)
        except ValueError:
            if not quiet:
                self.unsupported(node)
            return None

    def own_call(self, call: ast.Call, *, quiet: bool = False) -> Any:
        """``helper()`` where the file defines ``helper``: the literal it returns, if that is all it does."""
        assert isinstance(call.func, ast.Name)
        name, returned = call.func.id, self.functions[call.func.id]
        if call.args or call.keywords or returned is None:
            if not quiet:
                self.problem(call, f"{name}() is worked out when the launch file runs; fogiac reads only a function "
                                   "that takes no arguments and returns a literal: write the value here")
            return None
        return ast.literal_eval(returned)

    def call(self, call: ast.Call) -> Any:
        callee = _callee(call)
        if isinstance(call.func, ast.Name) and callee in self.functions:
            return self.own_call(call)
        if isinstance(call.func, ast.Attribute) and call.func.attr == "getLogger":
            return _LOGGER
        if callee in _DESCRIPTIONS:
            return "ld"
        if callee in _AWS:
            return self.aws(call)
        if callee == "find_cheapest_ec2_instance_type":
            return self.cheapest(call)
        if callee in _OTHER_CLOUDS:
            self.problem(call, f"FogROS2's {_OTHER_CLOUDS[callee]} machines are not imported: fogiac runs on AWS "
                               "(AWSCloudInstance, target aws) or on machines you have (target hosts)")
            return None
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
            if isinstance(call.args[0], ast.Call) and _callee(call.args[0]) == "LogInfo":
                return None  # a message at launch: nothing deployed
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
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in self.functions:
            value = self.own_call(node, quiet=quiet)
            if value is None:
                return None  # said where the call is
        elif isinstance(node, ast.Name) and self.values.get(node.id) is _FAILED:
            return None  # said where the name was bound
        else:
            value = self.values.get(node.id) if isinstance(node, ast.Name) else getattr(node, "value", None)
            value = value if isinstance(node, (ast.Name, ast.Constant)) else None
        if isinstance(value, str):
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
        given = kwargs.get("ec2_instance_type")
        kind: str | dict[str, Any] | None = "t2.micro"  # FogROS2's defaults
        if isinstance(given, ast.Call) and _callee(given) == "find_cheapest_ec2_instance_type":
            kind = self.cheapest(given)
        elif isinstance(given, ast.Name) and isinstance(self.values.get(given.id), dict):
            kind = self.values[given.id]
        elif given is not None:
            kind = self.string(given, "ec2_instance_type")
        disk = self.literal(kwargs["disk_size"]) if "disk_size" in kwargs else None
        if "ami_image" in kwargs and not any("ami_image" in n for n in self.notes):
            self.notes.append("ami_image dropped: fogiac picks each machine's image by its architecture "
                              "(Ubuntu 24.04, or AWS's Deep Learning image on GPU machines; amd64 or arm64)")
        if region is None or kind is None:
            return None
        aws = variant("aws")  # FogROS2's machines name EC2 types and regions
        for what, check, value in (("ec2_instance_type", aws.check_machine, kind), ("region", aws.check_region,
                                                                                      region)):
            try:
                if isinstance(value, str):
                    check(value)
            except FieldProblem as err:
                self.problem(kwargs.get(what, call), f"{what}: {err.message}")
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
        machine = self.call(where) if isinstance(where, ast.Call) and _callee(where) in (*_AWS, *_OTHER_CLOUDS) \
            else self.values.get(where.id) if isinstance(where, ast.Name) else None
        if machine is None or machine is _FAILED:
            return None  # said where the machine was made
        if not isinstance(machine, _Machine):
            self.problem(where, "machine must be an AWS(...) machine (FogROS2's other clouds are not imported)")
            return None
        if package is None or executable is None:
            return None
        node = _CloudNode(package, executable, name, machine, call.lineno)
        self.cloud.append(node)
        return node


    def nearest(self, stmt: ast.Assign) -> None:
        """``region, ami = find_nearest_region_and_ami(REGIONS)``: FogROS2 measures at launch time; fogiac
        takes the listed region nearest this machine's time zone (or the first) and says so."""
        target, call = stmt.targets[0], stmt.value
        assert isinstance(call, ast.Call)
        arg = call.args[0] if len(call.args) == 1 else None
        names = [t.id for t in target.elts if isinstance(t, ast.Name)] if isinstance(target, ast.Tuple) else []
        own = isinstance(arg, ast.Call) and isinstance(arg.func, ast.Name) and arg.func.id in self.functions
        listed = self.literal(arg, quiet=not own) if arg else None
        if own and listed is None:  # said at the call; what the names would hold is unknown, not wrong again
            self.values.update(dict.fromkeys(names, _FAILED))
            return None
        if not isinstance(listed, (dict, list, tuple)) or not listed or len(names) != 2 \
                or not all(isinstance(r, str) for r in listed):
            return self.problem(stmt, "find_nearest_region_and_ami needs a list or dict of regions (a literal, a "
                                      "name bound to one, or a function here returning one), unpacked as "
                                      "'region, ami = ...'")
        region, note = nearest(list(listed), zone=local_zone())
        self.values[names[0]], self.values[names[1]] = region, _AMI
        self.notes.append(note)
        return None

    def cheapest(self, call: ast.Call) -> dict[str, Any] | None:
        """``find_cheapest_ec2_instance_type(region, cpu_architecture, default_cores,
        default_threads_per_core, gpu)`` as the requirement ``plan`` resolves to the cheapest fit."""
        names = ("region_name", "cpu_architecture", "default_cores", "default_threads_per_core", "gpu")
        given = dict(zip(names, call.args, strict=False)) | {k.arg: k.value for k in call.keywords if k.arg}
        args = {k: self.literal(v) for k, v in given.items()}
        if args.get("cpu_architecture", "x86_64") != "x86_64":
            self.problem(call, "find_cheapest_ec2_instance_type for arm64: name a Graviton type instead "
                               "(fogiac's requirement takes vCPUs, memory and GPU)")
            return None
        cores, threads = args.get("default_cores", 2), args.get("default_threads_per_core", 1)
        if not isinstance(cores, int) or not isinstance(threads, int):
            self.problem(call, "find_cheapest_ec2_instance_type's cores and threads must be numbers")
            return None
        need: dict[str, Any] = {"vcpus": f"=={cores * threads}"}
        if args.get("gpu"):
            need["gpu"] = True
        return need


def _is_loop_over_names(stmt: ast.stmt) -> bool:
    """``for a in (x, y): ld.add_action(a)``: a loop over names bound earlier, nothing else."""
    return (isinstance(stmt, ast.For) and isinstance(stmt.target, ast.Name) and not stmt.orelse
            and isinstance(stmt.iter, (ast.Tuple, ast.List)) and all(isinstance(e, ast.Name) for e in stmt.iter.elts))


def _name(nodes: list[ast.expr]) -> str:
    return nodes[0].id if nodes and isinstance(nodes[0], ast.Name) else ""


def _callee(call: ast.Call) -> str:
    func = call.func
    return func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else ""


def _is_docstring(stmt: ast.stmt) -> bool:
    return isinstance(stmt, ast.Expr) and isinstance(stmt.value, ast.Constant) and isinstance(stmt.value.value, str)


def _returned_literal(function: ast.FunctionDef | ast.AsyncFunctionDef) -> ast.expr | None:
    """What ``function`` returns if it takes no arguments and does nothing but return a literal
    (after a docstring): FogROS2's examples list their regions and AMIs so. Else None."""
    body = [stmt for stmt in function.body if not _is_docstring(stmt)]
    arguments = function.args
    if isinstance(function, ast.AsyncFunctionDef) or function.decorator_list or len(body) != 1 \
            or not isinstance(body[0], ast.Return) or body[0].value is None \
            or arguments.args or arguments.posonlyargs or arguments.kwonlyargs or arguments.vararg or arguments.kwarg:
        return None
    try:
        ast.literal_eval(body[0].value)
    except (ValueError, TypeError, SyntaxError, MemoryError, RecursionError):
        return None
    return body[0].value


def convert(path: Path) -> tuple[dict, list[str], list[str], list[int]]:
    """The manifest's data, the nodes kept on the robot, notes for the header and each node's line in the
    launch file; or ManifestError."""
    source = str(path)
    text = read_source(path)
    screen_python(text, source=source)
    try:
        tree = ast.parse(text, filename=source)
    except SyntaxError as err:
        raise ManifestError([f"{source}:{err.lineno or 1}: not valid Python: {err.msg}"]) from None
    except (RecursionError, MemoryError):
        raise ManifestError([f"{source}:1: nested too deeply to read"]) from None
    reader = _Reader(source)
    try:
        reader.module(tree)
    except RecursionError:
        raise ManifestError([f"{source}:1: nested too deeply to read"]) from None
    if not reader.found_entry:
        reader.problems.append(f"{source}:1: no {_ENTRY}() here: not a ROS 2 launch file")
    regions = sorted({m.region for m in reader.machines})
    if len(regions) > 1:
        where = ", ".join(f"{r!r} at line {next(m.line for m in reader.machines if m.region == r)}" for r in regions)
        reader.problems.append(f"{source}:{reader.machines[-1].line}: machines in several regions ({where}): a "
                               "fogiac manifest deploys to one region; put the machines in one, or split the launch "
                               "file by region and import each part as a stack of its own")
    if reader.problems:
        raise ManifestError(reader.problems)
    nodes, notes, lines = _nodes(reader)
    notes = reader.notes + notes
    if not nodes:
        raise ManifestError([f"{source}:1: nothing here runs in the cloud (no CloudNode, no add_docker_container): "
                             "every node stays on the robot, so fogiac has nothing to deploy"])
    data = {"name": FromLaunch(_dns(path.name.removesuffix(".py").removesuffix(".launch"))),
            "ros": {"distro": DISTRO}, "cloud": {"provider": "aws", "region": FromLaunch(regions[0])}, "nodes": nodes}
    return data, reader.local, notes, lines


def _nodes(reader: _Reader) -> tuple[list[dict], list[str], list[int]]:
    """The manifest's nodes (every string from the file a :class:`FromLaunch`), notes, and their lines."""
    nodes: list[dict] = []
    notes: list[str] = []
    lines: list[int] = []
    taken: set[str] = set()

    def unique(name: str) -> str:
        base, n = _dns(name), 2
        name = base
        while name in taken:
            name, n = f"{base}-{n}", n + 1
        taken.add(name)
        return name

    def node(name: str, machine: _Machine, image: str, command: tuple[str, ...], line: int, **extra: Any) -> None:
        kind = machine.instance_type
        entry: dict[str, Any] = {"name": FromLaunch(unique(name)),
                                 "machine": FromLaunch(kind) if isinstance(kind, str) else kind,
                                 "image": FromLaunch(image)}
        if command:
            entry["command"] = [FromLaunch(word) for word in command]
        entry.update(extra)
        if machine.disk_gb:
            entry["disk_gb"] = max(8, machine.disk_gb)
        entry["topics"] = {"in": [], "out": []}
        nodes.append(entry)
        lines.append(line)

    for cloud in reader.cloud:
        image = f"ros:{DISTRO}-ros-base"
        node(cloud.name or cloud.executable, cloud.machine, image, ("ros2", "run", cloud.package, cloud.executable),
             cloud.line)
        notes.append(f"{nodes[-1]['name']}: FogROS2 pushed the robot's workspace; build an image FROM {image} "
                     f"holding package {cloud.package} and put it in image:")
    for machine in reader.machines:
        for command, line in machine.containers:
            parsed = docker_node(command)
            if parsed is None:
                raise ManifestError([f"{reader.source}:{line}: add_docker_container needs a 'docker run ... IMAGE' "
                                     "command"])
            image, args, env, gpus = parsed
            quoted = {FromLaunch(key): FromLaunch(value) for key, value in env.items()}
            extra: dict[str, Any] = ({"env": quoted} if env else {}) | ({"gpu": True} if gpus else {})
            node(image.rsplit("/", 1)[-1].split(":")[0], machine, image, args, line, **extra)
            if "-v" in command or "--volume" in command:
                notes.append(f"{nodes[-1]['name']}: the container's volumes (-v) name paths on FogROS2's machine; "
                             "not carried over")
    return nodes, notes, lines


def to_yaml(data: dict, *, source: Path, local: list[str], notes: list[str]) -> str:
    header = [f"# Imported from {source.name} (FogROS2) by `fogiac import`: read as text, never run.",
              "# Kept on the robot (not deployed by fogiac):"]
    header += [f"#   - {n}" for n in local] or ["#   (none)"]
    header += ["# To do before `fogiac up`:",
               "#   - list each node's topics (in: robot -> cloud, out: cloud -> robot); ROS 2 topics cross",
               "#     Zenoh's access control only when listed, and a FogROS2 launch file names none",
               f"#   - ros.distro is FogROS2's ({DISTRO}); set the robot's"]
    header += [f"#   - {n}" for n in notes]
    return dump(header, data)  # each header line one comment line, whatever the file's names hold


def import_launch(path: Path, *, out: Path | None = None) -> Converted:
    """Read, convert and validate; the manifest and its YAML text. Nothing is written here."""
    data, local, notes, lines = convert(path)
    text = to_yaml(data, source=path, local=local, notes=notes)
    manifest = validate(text, launch=path, base=(out or path).resolve().parent, node_lines=lines)
    return Converted(manifest, text, ())  # its notes are in the YAML's header, for the user to act on
