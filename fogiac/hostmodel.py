"""What runs on a provisioned host, as data: its folder layout, the facts found there, its services.

Why a module of its own: provisioning runs services on hosts and each middleware (``fogiac.net.<name>``)
contributes some of them (a ROS master, a relay's cloud end, a Zenoh router). Both describe them in
these terms, so this module sits below both: it imports neither ``fogiac.net`` nor ``fogiac.provision``,
and a middleware never has to import provisioning to say what a host runs.

- :class:`Layout`: fogiac's folders under its base folder on one host.
- :class:`Where`: the facts about one host that services depend on, found at provisioning time,
  among them its :class:`Runtime` (containers or native), which says how a ROS program or a node runs.
- :class:`Service`: one long-running process, rendered (:func:`make_service`) into a shell script and a
  systemd unit, compared by text before anything restarts.
- :class:`Launching`, :class:`NativeRos`: what a ROS generation and its middleware ask of a host.
"""

from __future__ import annotations

import hashlib
import shlex
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from fogiac.plan.model import HostSpec, NodeSpec, Plan


def _q(value: object) -> str:
    return shlex.quote(str(value))


@dataclass(frozen=True)
class Layout:
    """Where fogiac keeps things under its base folder on one host, and whose they are."""

    base: str
    stack: str = ""  # names what lives outside the folder (systemd units); "" only where none is made

    @property
    def bin(self) -> str:
        return f"{self.base}/bin"

    @property
    def run(self) -> str:
        return f"{self.base}/run"

    @property
    def services(self) -> str:
        return f"{self.base}/services"

    @property
    def ws(self) -> str:
        return f"{self.base}/ws"

    @property
    def build(self) -> str:
        return f"{self.base}/build"

    @property
    def env(self) -> str:
        return f"{self.base}/env"

    @property
    def state(self) -> str:
        return f"{self.base}/state"

    @property
    def certs(self) -> str:
        return f"{self.base}/certs"

    @property
    def lib(self) -> str:
        return f"{self.base}/lib"

    @property
    def ros_home(self) -> str:
        return f"{self.base}/ros"

    @property
    def tmp(self) -> str:
        return f"{self.base}/tmp"

    @property
    def supervisor(self) -> str:
        return f"{self.base}/bin/fogiac-supervise.py"

    @property
    def env_file(self) -> str:
        return f"{self.base}/env/ros.sh"

    def workspace(self, local_path: str) -> str:
        """Each pushed workspace gets a folder named after it and its local path."""
        tag = hashlib.sha256(local_path.encode()).hexdigest()[:8]
        name = local_path.rstrip("/").rsplit("/", 1)[-1] or "ws"
        return f"{self.base}/ws/{name}-{tag}"


@dataclass(frozen=True)
class NodeRun:
    """How one node runs on a runtime: its command and what its service script sets up first."""

    command: str
    check: str
    pre: tuple[str, ...] = ()
    package_path: str = ""
    python_path: str = ""
    cwd: str = ""
    bin_path: str = ""
    env: tuple[tuple[str, str], ...] = ()  # the node's own env, exported by its script
    files: tuple[tuple[str, str, int], ...] = ()  # (path, text, mode) its command reads (an --env-file)


class Runtime(Protocol):
    """How a host runs ROS programs and nodes: in containers or natively (``fogiac.provision.runtimes``).
    Chosen once per host when it is provisioned; services ask it instead of testing its name."""

    @property
    def name(self) -> str: ...  # "container" or "native", as reports and the manifest's cloud.runtime say it

    def program(self, plan: Plan, spec: HostSpec, where: Where, *, name: str, argv: tuple[str, ...],
                env: tuple[tuple[str, str], ...]) -> tuple[str, tuple[str, ...]]:
        """A ROS program (``roscore``) from the plan's ROS image or the host's own ROS, with the nodes'
        ROS ``env``: its command line, and what its service script runs first."""
        ...

    def node(self, node: NodeSpec, plan: Plan, spec: HostSpec, where: Where) -> NodeRun:
        """How ``node`` runs on the host."""
        ...


@dataclass(frozen=True)
class Where:
    """The facts about one host the services depend on, found at provisioning time."""

    layout: Layout
    runtime: Runtime
    master_port: int
    relay_port: int  # the port the edge dials on the host (the middleware's)
    ros_address: str
    python: str
    code_root: str  # the folder holding fogiac/ and workloads/ for `python -m`
    user: str = "root"
    workspace_digests: tuple[tuple[str, str], ...] = ()  # (local path, digest) of pushed workspaces
    engine: str = "docker"  # the container engine's command on the host (container runtime)
    init: bool = False  # the engine runs nodes under an init (--init), so a stop's SIGTERM reaches them at once
    images: tuple[tuple[str, str], ...] = ()  # (node, tag) of images built on the host
    workload_python: str = ""  # interpreter of workload nodes on a native host ('' : python)
    launch_bin: str = ""  # a venv's bin folder put first on native launch nodes' PATH ('' : none)
    ros_image: str = ""  # the ROS image nodes run in on this host, when not the plan's own (see node_image)

    @property
    def listen(self) -> str:
        """A host reached over loopback (the local target) never listens beyond it; others listen on
        every interface and the security group (or the lab's network) decides who reaches the port."""
        return "127.0.0.1" if self.ros_address.startswith("127.") else "0.0.0.0"


@dataclass(frozen=True)
class Service:
    """One long-running process: its supervisor name, shell script, unit, and health check."""

    name: str
    script: str
    check: str  # master | node | any | alive
    unit: str
    files: tuple[tuple[str, str, int], ...] = ()  # (path, text, mode) the script reads; written before it starts

    @property
    def digest(self) -> str:
        return hashlib.sha256(self.script.encode()).hexdigest()


@dataclass(frozen=True)
class Launching:
    """How a ROS generation builds a pushed workspace and runs one package's launch file from it, and how it
    puts one instance of a node in a robot's namespace (``serve: per_robot``)."""

    command: tuple[str, ...]  # what comes before PACKAGE FILE: ("roslaunch", "--wait"), ("ros2", "launch")
    has_packages: str  # a shell test, in the workspace's root: it has packages to build
    tool: str  # the build tool's command
    build: str  # the build, run in the workspace's root after its env scripts
    overlay: str  # the setup script a build leaves, relative to the workspace's root
    package_path: bool  # True: packages are found through ROS_PACKAGE_PATH (natively, that alone)
    image_has_tool: bool  # True: the ROS image always carries ``tool``; else the build asks first
    # (robot, the node's listed topics) -> the arguments a node's command takes to run as that robot's instance:
    # in /<robot>, its listed topics remapped there. None: this generation runs no per-robot instances yet.
    instance_args: Callable[[str, tuple[str, ...]], tuple[str, ...]] | None = None

    def build_in_image(self) -> str:
        """The build inside the ROS image, when the workspace has packages; an image without the build
        tool fails here in one line rather than leaving the node to fail at launch ("package not found")."""
        if self.image_has_tool:
            return f"if {self.has_packages}; then {self.build} >/dev/null; fi"
        missing = (f"the ROS image has no {self.tool} to build this workspace's packages; "
                   f"use an image that has it (a ros-base image)")
        return (f"if {self.has_packages}; then command -v {self.tool} >/dev/null || "
                f"{{ echo {_q(missing)} >&2; exit 1; }}; {self.build} >/dev/null; fi")

    def build_native(self, env_file: str) -> str:
        """The build on a native host, in the nodes' environment, when it has packages and the tool."""
        return (f"if {self.has_packages} && command -v {self.tool} >/dev/null; "
                f"then . {env_file} && {self.build} >/dev/null; fi")


@dataclass(frozen=True)
class NativeRos:
    """What a native host must have for a middleware's nodes, how to tell, and how to get it."""

    needs: str  # in words, for the refusal: "roscore, roslaunch, rospy"
    check: str  # a shell command that exits 0 when the host has it all
    packages: tuple[str, ...]  # what installs it
    install: str  # the script that installs them (run as root), rendered
    by_hand: str  # the command a person runs instead, for the refusal
    origin: str = ""  # where the packages come from, when not the OS's own archive
    setup: str = ""  # a script the nodes' environment sources first, when the host has it
    image_layer: str = ""  # Dockerfile lines that add it to the ROS image when that lacks it ('' : never needed)
    probed: tuple[str, ...] = ()  # probe flags that, all present, answer ``check`` at no cost


def master_uri(where: Where) -> str:
    return f"http://127.0.0.1:{where.master_port}"


def container_name(stack: str, name: str) -> str:
    """Containers carry the stack, so two stacks on one machine never take each other's names. A
    per-robot instance (``slam@arm1``) is ``slam.arm1`` there: engines take no ``@``, and node names no dot."""
    return f"fogiac-{stack}-{name.replace('@', '.')}"


def unit_name(stack: str, name: str) -> str:
    """A service's systemd unit carries the stack too: units live in one folder for the whole machine."""
    return f"fogiac-{stack}-{name}.service" if stack else f"fogiac-{name}.service"


def ros_image(plan: Plan) -> str:
    return f"ros:{plan.ros_distro}-ros-core"


def node_image(plan: Plan, where: Where) -> str:
    """The ROS image nodes run in on the host: the plan's, or the one provisioning gave what the
    middleware needs (rmw_zenoh_cpp), which the official image lacks."""
    return where.ros_image or ros_image(plan)


def instance_name(node: str, robot: str) -> str:
    """A per-robot node's instance for ``robot``: its service is ``node-slam@arm1``, as the robot's edge end
    is ``relay-edge-HOST@arm1``."""
    return f"{node}@{robot}"


def node_instances(plan: Plan, node: NodeSpec) -> tuple[str, ...]:
    """The names ``node`` runs under on its host: its own, or one per robot it serves (``serve: per_robot``)."""
    return tuple(instance_name(node.name, robot) for robot in plan.robots_of(node)) if node.per_robot else (node.name,)


def node_env_file(layout: Layout, node: str) -> str:
    return f"{layout.env}/node-{node}.env"


def secret_file(layout: Layout, node: str) -> str:
    """A native node's secrets, sourced by its service script (0600; a container node's are in its env file)."""
    return f"{layout.env}/node-{node}.secret.sh"


def make_service(name: str, *, plan: Plan, spec: HostSpec, where: Where, command: str, check: str,
                 env: tuple[tuple[str, str], ...] = (), pre: tuple[str, ...] = (), package_path: str = "",
                 python_path: str = "", cwd: str = "", notes: tuple[str, ...] = (), after: str = "",
                 files: tuple[tuple[str, str, int], ...] = (), bin_path: str = "") -> Service:
    """A service's script and unit, rendered; ``after``: the service name its unit starts after."""
    from fogiac.render import render  # noqa: PLC0415 (jinja2: `fogiac validate` asks for Launching, not this)

    layout = where.layout
    # A file the script reads is named with its digest, so changing it restarts the service.
    notes += tuple(f"{path} sha256 {hashlib.sha256(text.encode()).hexdigest()}" for path, text, _ in files)
    script_path = f"{layout.services}/{name}.sh"
    script = render(
        "provision/service.sh.j2", name=name, host=spec.name, stack=plan.stack, notes=notes,
        env_file=layout.env_file, ros_home=layout.ros_home, env=env, package_path=package_path,
        python_path=python_path, cwd=cwd or layout.base, pre=pre, command=command, bin_path=bin_path,
    )
    unit = render("provision/systemd.service.j2", name=name, host=spec.name, stack=plan.stack, user=where.user,
                  script=script_path, after=unit_name(plan.stack, after) if after else "")
    return Service(name=name, script=script, check=check, unit=unit, files=files)


def autostop_service(plan: Plan, spec: HostSpec, where: Where, *, stats: str, after: str) -> Service | None:
    """The idle watchdog (``fogiac.provision.autostop``), when the plan has autostop on: it reads
    ``stats``, which the middleware's service ``after`` writes."""
    if plan.autostop is None:
        return None
    stop = plan.autostop
    command = (f"{_q(where.python)} -m fogiac.provision.autostop --stats {_q(stats)} "
               f"--run {_q(where.layout.run)} --idle-s {stop.idle_s:g} --action {stop.action} --power {stop.power}")
    return make_service("autostop", plan=plan, spec=spec, where=where, command=command, check="alive",
                        python_path=where.code_root, after=after)
