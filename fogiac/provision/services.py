"""What runs on a host, decided purely from the plan: the ROS master, one service per node, the relay.

Why pure: the exact ``docker run`` lines, service scripts and systemd units are what a reviewer
checks, and they must be testable on a machine without Docker or systemd. The steps in
:mod:`.steps` only compare these texts with what the host has and act on differences.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import dataclass

from fogiac.errors import ProvisionError
from fogiac.net.rosenv import side_env
from fogiac.plan.model import HostSpec, NodeSpec, Plan
from fogiac.provision.host import q
from fogiac.render import render

CONTAINER = "container"
NATIVE = "native"
_WS_MOUNT = "/fogiac/ws"


@dataclass(frozen=True)
class Layout:
    """Where fogiac keeps things under its base folder on one host."""

    base: str

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
class Where:
    """The facts about one host the services depend on, found at provisioning time."""

    layout: Layout
    runtime: str  # CONTAINER or NATIVE
    master_port: int
    relay_port: int
    ros_address: str
    python: str
    code_root: str  # the folder holding fogiac/ and workloads/ for `python -m`
    user: str = "root"
    workspace_digests: tuple[tuple[str, str], ...] = ()  # (local path, digest) of pushed workspaces


@dataclass(frozen=True)
class Service:
    """One long-running process: its supervisor name, shell script, unit, and health check."""

    name: str
    script: str
    check: str  # master | node | any | alive
    unit: str

    @property
    def digest(self) -> str:
        return hashlib.sha256(self.script.encode()).hexdigest()


def master_uri(where: Where) -> str:
    return f"http://127.0.0.1:{where.master_port}"


def container_name(node: str) -> str:
    return f"fogiac-{node}"


def ros_image(plan: Plan) -> str:
    return f"ros:{plan.ros_distro}-ros-core"


def workload_image(workload: str) -> str:
    return f"fogiac/{workload}:latest"


def node_env(node: NodeSpec, where: Where) -> tuple[tuple[str, str], ...]:
    """ROS_MASTER_URI, ROS_IP (or ROS_HOSTNAME) first, then the node's own variables."""
    ros = side_env(side="cloud", master_uri=master_uri(where), address=where.ros_address).env
    return tuple(ros.items()) + node.env


def docker_run(node: NodeSpec, *, plan: Plan, spec: HostSpec, where: Where) -> str:
    """The exact ``docker run`` line of a node on a container host (``--gpus all`` on GPU types only)."""
    volumes: tuple[tuple[str, str], ...] = ()
    env = node_env(node, where)
    if node.kind == "image":
        image, command = node.image or "", node.command
    elif node.kind == "launch" and node.launch is not None:
        image, command = ros_image(plan), ("roslaunch", "--wait", node.launch.package, node.launch.file)
        volumes = ((where.layout.workspace(node.launch.workspace), _WS_MOUNT),)
        env += (("ROS_PACKAGE_PATH", f"{_WS_MOUNT}/src:{_WS_MOUNT}"),)
    else:
        image, command = workload_image(node.workload or ""), ("python", "-m", f"workloads.{node.workload}", "node")
    return render("provision/docker_run.j2", gpus=spec.has_gpu, container=container_name(node.name), env=env,
                  volumes=volumes, image=image, command=command).strip()


@dataclass(frozen=True)
class _NodeRun:
    """How one node runs on a runtime: its command and what its service script sets up first."""

    command: str
    check: str
    pre: tuple[str, ...] = ()
    package_path: str = ""
    python_path: str = ""
    cwd: str = ""


def _container_node(node: NodeSpec, plan: Plan, spec: HostSpec, where: Where) -> _NodeRun:
    name = container_name(node.name)
    return _NodeRun(command=docker_run(node, plan=plan, spec=spec, where=where),
                    pre=(f"docker rm -f {name} >/dev/null 2>&1 || true",), check="any")


# roslaunch --wait: without it, a roslaunch that starts before the host's master service would
# start a master of its own on the same port and make the real one crash-loop.
def _native_node(node: NodeSpec, plan: Plan, spec: HostSpec, where: Where) -> _NodeRun:
    if node.kind == "image":
        raise ProvisionError(
            f"{spec.name}: node {node.name} runs image {node.image} but the host has no working "
            "container engine (`docker info` failed); install Docker there or use a launch/workload node"
        )
    if node.kind == "launch" and node.launch is not None:
        ws = where.layout.workspace(node.launch.workspace)
        return _NodeRun(command=f"roslaunch --wait {q(node.launch.package)} {q(node.launch.file)}",
                        package_path=f"{ws}/src:{ws}", check="node", cwd=ws)
    return _NodeRun(command=f"{q(where.python)} -m workloads.{node.workload} node", python_path=where.code_root,
                    check="node")


_NODE_RUNTIMES: dict[str, Callable[[NodeSpec, Plan, HostSpec, Where], _NodeRun]] = {
    CONTAINER: _container_node,
    NATIVE: _native_node,
}


def _service(name: str, *, plan: Plan, spec: HostSpec, where: Where, command: str, check: str,
             env: tuple[tuple[str, str], ...] = (), pre: tuple[str, ...] = (), package_path: str = "",
             python_path: str = "", cwd: str = "", notes: tuple[str, ...] = (), after: str = "") -> Service:
    layout = where.layout
    script_path = f"{layout.services}/{name}.sh"
    script = render(
        "provision/service.sh.j2", name=name, host=spec.name, stack=plan.stack, notes=notes,
        env_file=layout.env_file, ros_home=layout.ros_home, env=env, package_path=package_path,
        python_path=python_path, cwd=cwd or layout.base, pre=pre, command=command,
    )
    unit = render("provision/systemd.service.j2", name=name, host=spec.name, stack=plan.stack, user=where.user,
                  script=script_path, after=after)
    return Service(name=name, script=script, check=check, unit=unit)


def master_service(plan: Plan, spec: HostSpec, where: Where) -> Service:
    if where.runtime == CONTAINER:
        command = render("provision/docker_run.j2", gpus=False, container="fogiac-ros-master", env=(),
                         volumes=(), image=ros_image(plan), command=("roscore", "-p", str(where.master_port))).strip()
        pre: tuple[str, ...] = ("docker rm -f fogiac-ros-master >/dev/null 2>&1 || true",)
    else:
        command, pre = f"roscore -p {where.master_port}", ()
    return _service("ros-master", plan=plan, spec=spec, where=where, command=command, check="master", pre=pre)


def node_services(plan: Plan, spec: HostSpec, where: Where) -> tuple[Service, ...]:
    """One service per node placed on ``spec``, in plan order."""
    digests = dict(where.workspace_digests)
    out = []
    for name in spec.nodes:
        node = plan.node(name)
        parts = _NODE_RUNTIMES[where.runtime](node, plan, spec, where)
        notes: tuple[str, ...] = ()
        if node.launch is not None:
            notes = (f"workspace {node.launch.workspace} digest {digests.get(node.launch.workspace, 'unknown')}",)
        out.append(_service(
            f"node-{name}", plan=plan, spec=spec, where=where, command=parts.command, check=parts.check,
            env=node.env if where.runtime == NATIVE else (), pre=parts.pre, package_path=parts.package_path,
            python_path=parts.python_path, cwd=parts.cwd, notes=notes, after="fogiac-ros-master.service",
        ))
    return tuple(out)


def relay_service(plan: Plan, spec: HostSpec, where: Where) -> Service:
    # A host reached over loopback (the local target) never listens beyond it; others listen on
    # every interface and the security group (or the lab's network) decides who reaches the port.
    listen = "127.0.0.1" if where.ros_address.startswith("127.") else "0.0.0.0"
    route = next((r for r in plan.relay if r.host == spec.name), None)
    policy = " ".join(q(arg) for arg in route.policy_argv()) if route is not None else ""
    command = (f"{q(where.python)} -m fogiac relay cloud --listen {listen}:{where.relay_port} "
               f"--master {master_uri(where)} --certs {q(where.layout.certs)} --stats-file {q(relay_stats(where))} "
               f"{policy}").rstrip()
    return _service("relay-cloud", plan=plan, spec=spec, where=where, command=command, check="alive",
                    python_path=where.code_root, after="fogiac-ros-master.service")


def relay_stats(where: Where) -> str:
    """Where the relay's cloud end writes its live figures, which the autostop watchdog reads."""
    return f"{where.layout.run}/relay-cloud.stats.json"


def autostop_service(plan: Plan, spec: HostSpec, where: Where) -> Service | None:
    """The idle watchdog (:mod:`fogiac.provision.autostop`), when the plan has autostop on."""
    if plan.autostop is None:
        return None
    stop = plan.autostop
    command = (f"{q(where.python)} -m fogiac.provision.autostop --stats {q(relay_stats(where))} "
               f"--run {q(where.layout.run)} --idle-s {stop.idle_s:g} --action {stop.action} --power {stop.power}")
    return _service("autostop", plan=plan, spec=spec, where=where, command=command, check="alive",
                    python_path=where.code_root, after="fogiac-relay-cloud.service")
