"""What runs on a host, decided purely from the plan: the ROS master, one service per node, the relay.

Why pure: the exact ``docker run`` lines, service scripts and systemd units are what a reviewer
checks, and they must be testable on a machine without Docker or systemd. The steps in
:mod:`.steps` only compare these texts with what the host has and act on differences.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from fogiac.errors import ProvisionError
from fogiac.net import middleware
from fogiac.net.relay.middleware import MASTER
from fogiac.plan.model import HostSpec, NodeSpec, Plan
from fogiac.provision.host import q
from fogiac.render import render

CONTAINER = "container"
NATIVE = "native"
_WS_MOUNT = "/fogiac/ws"


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
    engine: str = "docker"  # the container engine's command on the host (runtime CONTAINER)
    images: tuple[tuple[str, str], ...] = ()  # (node, tag) of images built on the host
    workload_python: str = ""  # interpreter of workload nodes on a native host ('' : python)
    launch_bin: str = ""  # a venv's bin folder put first on native launch nodes' PATH ('' : none)
    ros_image: str = ""  # the ROS image nodes run in on this host, when not the plan's own (see node_image)


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


def master_uri(where: Where) -> str:
    return f"http://127.0.0.1:{where.master_port}"


def container_name(stack: str, name: str) -> str:
    """Containers carry the stack, so two stacks on one machine never take each other's names."""
    return f"fogiac-{stack}-{name}"


def unit_name(stack: str, name: str) -> str:
    """A service's systemd unit carries the stack too: units live in one folder for the whole machine."""
    return f"fogiac-{stack}-{name}.service" if stack else f"fogiac-{name}.service"


def ros_image(plan: Plan) -> str:
    return f"ros:{plan.ros_distro}-ros-core"


def node_image(plan: Plan, where: Where) -> str:
    """The ROS image nodes run in on the host: the plan's, or the one provisioning gave what the
    middleware needs (rmw_zenoh_cpp), which the official image lacks."""
    return where.ros_image or ros_image(plan)


def node_env_file(layout: Layout, node: str) -> str:
    return f"{layout.env}/node-{node}.env"


def env_script(env: Mapping[str, str], *, host: str, setup: str = "") -> str:
    """The env file every service script on a host sources: the middleware's environment for nodes,
    after ``setup`` (the ROS installation's own script, when the host has it)."""
    first = f"if [ -f {q(setup)} ]; then . {q(setup)}; fi\n" if setup else ""
    return f"# fogiac: environment of the nodes on {host}. Source it: . ros.sh\n" + first + "".join(
        f"export {key}={q(value)}\n" for key, value in env.items())


def env_file_text(env: tuple[tuple[str, str], ...]) -> str:
    """``KEY=VALUE`` lines as ``--env-file`` reads them: values taken literally, no quoting."""
    for key, value in env:
        if "\n" in value or "\r" in value:
            raise ProvisionError(f"env {key}: a value cannot hold a line break")
    return "".join(f"{key}={value}\n" for key, value in env)


def ros_env(plan: Plan, where: Where) -> tuple[tuple[str, str], ...]:
    """The middleware's environment for nodes (ROS_MASTER_URI and ROS_IP; RMW_IMPLEMENTATION and the
    router): what every container on the host is given."""
    return tuple(middleware.deployment(plan.middleware).node_env(where).items())


def _built(node: NodeSpec, where: Where) -> str:
    tag = dict(where.images).get(node.name)
    if tag is None:
        raise ProvisionError(f"node {node.name}: its image was not built on the host before its service")
    return tag


def docker_run(node: NodeSpec, *, plan: Plan, spec: HostSpec, where: Where) -> str:
    """The exact ``docker run`` line of a node on a container host (``--gpus all`` on GPU types only).

    The node's own ``env:`` travels in a 0600 env file, never on the command line; ``--`` ends
    the engine's options, so nothing in the image or command is read as one.
    """
    volumes: tuple[tuple[str, str, str], ...] = ()
    env, workdir = ros_env(plan, where), ""
    if node.kind == "image":
        image, command = (node.image or _built(node, where)), node.command
    elif node.kind == "command":
        image, command = node_image(plan, where), node.command
    elif node.kind == "launch" and node.launch is not None:
        image = _built(node, where) if node.launch.requirements else node_image(plan, where)
        launching = middleware.get(plan.middleware).launching
        command = ("bash", "-c", f"{_source_overlay(_WS_MOUNT, launching.overlay)}; exec "
                   f"{' '.join(launching.command)} \"$0\" \"$1\"", node.launch.package, node.launch.file)
        volumes = ((where.layout.workspace(node.launch.workspace), _WS_MOUNT, "ro"),)
        if launching.package_path:
            env += (("ROS_PACKAGE_PATH", f"{_WS_MOUNT}/src:{_WS_MOUNT}"),)
        workdir = _WS_MOUNT
    else:
        image, command = _built(node, where), ("python", "-m", f"workloads.{node.workload}", "node")
    return render("provision/docker_run.j2", engine=where.engine, stack=plan.stack, host=spec.name,
                  gpus=spec.has_gpu, container=container_name(plan.stack, node.name), env=env,
                  env_file=node_env_file(where.layout, node.name) if node.env else "", volumes=volumes,
                  workdir=workdir, image=image, command=command).strip()


def _source_overlay(ws: str, overlay: str) -> str:
    """Source what the workspace's build left (catkin's devel/, colcon's install/), when it built."""
    setup = q(f"{ws}/{overlay}")
    return f"if [ -f {setup} ]; then . {setup}; fi"


def workspace_build_command(plan: Plan, where: Where, workspace: str, scripts: tuple[str, ...]) -> str:
    """Build a pushed workspace inside the ROS image, the way FogROS built on the cloud: each env
    script sourced in order, then the ROS generation's build (catkin_make, colcon) when it has packages."""
    steps = [f". {q(_WS_MOUNT + '/.fogiac-setup/' + s)}" for s in scripts]
    steps.append(middleware.get(plan.middleware).launching.build_in_image())
    return (f"{where.engine} run --rm --network host --volume {q(where.layout.workspace(workspace) + ':' + _WS_MOUNT)} "
            f"--workdir {_WS_MOUNT} -- {q(node_image(plan, where))} bash -ec {q('; '.join(steps))}")


@dataclass(frozen=True)
class _NodeRun:
    """How one node runs on a runtime: its command and what its service script sets up first."""

    command: str
    check: str
    pre: tuple[str, ...] = ()
    package_path: str = ""
    python_path: str = ""
    cwd: str = ""
    bin_path: str = ""


def _container_node(node: NodeSpec, plan: Plan, spec: HostSpec, where: Where) -> _NodeRun:
    name = container_name(plan.stack, node.name)
    return _NodeRun(command=docker_run(node, plan=plan, spec=spec, where=where),
                    pre=(f"{where.engine} rm -f {name} >/dev/null 2>&1 || true",), check="any")


def _native_node(node: NodeSpec, plan: Plan, spec: HostSpec, where: Where) -> _NodeRun:
    if node.kind == "image":
        raise ProvisionError(
            f"{spec.name}: node {node.name} runs image {node.image} but the host has no working "
            "container engine (`docker info` failed); install Docker there or use a launch/workload node"
        )
    if node.kind == "command":
        return _NodeRun(command=" ".join(q(arg) for arg in node.command), check="alive")
    if node.kind == "launch" and node.launch is not None:
        ws = where.layout.workspace(node.launch.workspace)
        launching = middleware.get(plan.middleware).launching
        # ROS 1 finds the package through ROS_PACKAGE_PATH; ROS 2 through its build's overlay, sourced
        # over the distro's setup.bash (the env file) and the env scripts' build.
        # A node script run by `#!/usr/bin/env python3` (ROS's convention) finds the venv's python first.
        return _NodeRun(command=" ".join((*launching.command, q(node.launch.package), q(node.launch.file))),
                        package_path=f"{ws}/src:{ws}" if launching.package_path else "", check="node", cwd=ws,
                        pre=() if launching.package_path else (_source_overlay(ws, launching.overlay),),
                        bin_path=where.launch_bin if node.launch.requirements else "")
    python = where.workload_python or where.python
    return _NodeRun(command=f"{q(python)} -m workloads.{node.workload} node", python_path=where.code_root,
                    check="node")


_NODE_RUNTIMES: dict[str, Callable[[NodeSpec, Plan, HostSpec, Where], _NodeRun]] = {
    CONTAINER: _container_node,
    NATIVE: _native_node,
}


def _service(name: str, *, plan: Plan, spec: HostSpec, where: Where, command: str, check: str,
             env: tuple[tuple[str, str], ...] = (), pre: tuple[str, ...] = (), package_path: str = "",
             python_path: str = "", cwd: str = "", notes: tuple[str, ...] = (), after: str = "",
             files: tuple[tuple[str, str, int], ...] = (), bin_path: str = "") -> Service:
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
                  script=script_path, after=after)
    return Service(name=name, script=script, check=check, unit=unit, files=files)


make_service = _service  # for the middlewares' own services (fogiac.net.<variant>.deploy)


def master_service(plan: Plan, spec: HostSpec, where: Where) -> Service:
    if where.runtime == CONTAINER:
        # ROS_IP in the container: the master advertises (and, on loopback, binds) the host's ROS address.
        name = container_name(plan.stack, f"{spec.name}-{MASTER}")
        command = render("provision/docker_run.j2", engine=where.engine, stack=plan.stack, host=spec.name, gpus=False,
                         container=name, env=ros_env(plan, where), env_file="", volumes=(), workdir="",
                         image=ros_image(plan), command=("roscore", "-p", str(where.master_port))).strip()
        pre: tuple[str, ...] = (f"{where.engine} rm -f {name} >/dev/null 2>&1 || true",)
    else:
        command, pre = f"roscore -p {where.master_port}", ()
    return _service(MASTER, plan=plan, spec=spec, where=where, command=command, check="master", pre=pre)


def node_services(plan: Plan, spec: HostSpec, where: Where) -> tuple[Service, ...]:
    """One service per node placed on ``spec``, in plan order. Without a ROS master (ROS 2) a node's
    health is its process running: there is nothing to register with."""
    digests = dict(where.workspace_digests)
    chosen = middleware.get(plan.middleware)
    master, after = chosen.node_master, unit_name(plan.stack, chosen.nodes_after)
    out = []
    for name in spec.nodes:
        node = plan.node(name)
        parts = _NODE_RUNTIMES[where.runtime](node, plan, spec, where)
        notes: tuple[str, ...] = ()
        if node.launch is not None:
            notes = (f"workspace {node.launch.workspace} digest {digests.get(node.launch.workspace, 'unknown')}",)
        in_container = where.runtime == CONTAINER
        files = ((node_env_file(where.layout, name), env_file_text(node.env), 0o600),) if in_container and node.env \
            else ()
        out.append(_service(
            f"node-{name}", plan=plan, spec=spec, where=where, command=parts.command,
            check=parts.check if master else "alive",
            env=() if in_container else node.env, pre=parts.pre, package_path=parts.package_path,
            python_path=parts.python_path, cwd=parts.cwd, notes=notes, after=after,
            files=files, bin_path=parts.bin_path,
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
                    python_path=where.code_root, after=unit_name(plan.stack, MASTER))


def relay_stats(where: Where) -> str:
    """Where the relay's cloud end writes its live figures, which the autostop watchdog reads."""
    return f"{where.layout.run}/relay-cloud.stats.json"


def autostop_service(plan: Plan, spec: HostSpec, where: Where, *, stats: str, after: str) -> Service | None:
    """The idle watchdog (:mod:`fogiac.provision.autostop`), when the plan has autostop on: it reads
    ``stats``, which the middleware's service ``after`` writes."""
    if plan.autostop is None:
        return None
    stop = plan.autostop
    command = (f"{q(where.python)} -m fogiac.provision.autostop --stats {q(stats)} "
               f"--run {q(where.layout.run)} --idle-s {stop.idle_s:g} --action {stop.action} --power {stop.power}")
    return _service("autostop", plan=plan, spec=spec, where=where, command=command, check="alive",
                    python_path=where.code_root, after=unit_name(plan.stack, after))
