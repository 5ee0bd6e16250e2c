"""The container runtime: the ROS master and every node in a container (docker, else podman) on the host.

Nodes run in the ROS image (or one built over it with what the middleware needs) or in images built on
the host from their recipes; pushed workspaces build inside the ROS image. The ``docker run`` lines are
rendered purely here, so a reviewer can check their exact text on a machine without an engine.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

from fogiac.errors import ProvisionError
from fogiac.hostmodel import NativeRos, NodeRun, Where, container_name, node_env_file, node_image, ros_image
from fogiac.net import middleware
from fogiac.plan.model import HostSpec, NodeSpec, Plan
from fogiac.provision import images, secrets, workload
from fogiac.provision.host import q
from fogiac.provision.probe import Facts
from fogiac.provision.runtimes.base import CHANGED, OK, Run, StepResult, source_overlay
from fogiac.render import render

_WS_MOUNT = "/fogiac/ws"


def ros_env(plan: Plan, where: Where) -> tuple[tuple[str, str], ...]:
    """The middleware's environment for nodes (ROS_MASTER_URI and ROS_IP; RMW_IMPLEMENTATION and the
    router): what every container on the host is given."""
    return tuple(middleware.deployment(plan.middleware).node_env(where).items())


def env_file_text(env: tuple[tuple[str, str], ...]) -> str:
    """``KEY=VALUE`` lines as ``--env-file`` reads them: values taken literally, no quoting."""
    for key, value in env:
        if "\n" in value or "\r" in value:
            raise ProvisionError(f"env {key}: a value cannot hold a line break")
    return "".join(f"{key}={value}\n" for key, value in env)


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
        command = ("bash", "-c", f"{source_overlay(_WS_MOUNT, launching.overlay)}; exec "
                   f"{' '.join(launching.command)} \"$0\" \"$1\"", node.launch.package, node.launch.file)
        volumes = ((where.layout.workspace(node.launch.workspace), _WS_MOUNT, "ro"),)
        if launching.package_path:
            env += (("ROS_PACKAGE_PATH", f"{_WS_MOUNT}/src:{_WS_MOUNT}"),)
        workdir = _WS_MOUNT
    else:
        image, command = _built(node, where), ("python", "-m", workload.package(node.workload or ""), "node")
    return render("provision/docker_run.j2", engine=where.engine, init=where.init, stack=plan.stack, host=spec.name,
                  gpus=spec.has_gpu, container=container_name(plan.stack, node.name), env=env,
                  env_file=node_env_file(where.layout, node.name) if node.env or node.secrets else "", volumes=volumes,
                  workdir=workdir, image=image, command=command).strip()


def workspace_build_command(plan: Plan, where: Where, workspace: str, scripts: tuple[str, ...]) -> str:
    """Build a pushed workspace inside the ROS image, the way FogROS built on the cloud: each env
    script sourced in order, then the ROS generation's build (catkin_make, colcon) when it has packages."""
    steps = [f". {q(_WS_MOUNT + '/.fogiac-setup/' + s)}" for s in scripts]
    steps.append(middleware.get(plan.middleware).launching.build_in_image())
    return (f"{where.engine} run --rm --network host --volume {q(where.layout.workspace(workspace) + ':' + _WS_MOUNT)} "
            f"--workdir {_WS_MOUNT} -- {q(node_image(plan, where))} bash -ec {q('; '.join(steps))}")


def _remove_first(where: Where, name: str) -> tuple[str, ...]:
    return (f"{where.engine} rm -f {name} >/dev/null 2>&1 || true",)


@dataclass(frozen=True)
class ContainerRuntime:
    name: str = "container"
    nodes_on_host: bool = False  # each node's requirements go in its image

    def program(self, plan: Plan, spec: HostSpec, where: Where, *, name: str, argv: tuple[str, ...],
                env: tuple[tuple[str, str], ...]) -> tuple[str, tuple[str, ...]]:
        container = container_name(plan.stack, name)
        command = render("provision/docker_run.j2", engine=where.engine, init=where.init, stack=plan.stack,
                         host=spec.name, gpus=False, container=container, env=env, env_file="", volumes=(), workdir="",
                         image=ros_image(plan), command=argv).strip()
        return command, _remove_first(where, container)

    def node(self, node: NodeSpec, plan: Plan, spec: HostSpec, where: Where) -> NodeRun:
        # The node's env and its secrets (read now, on the operator's machine) in one 0600 file on the host.
        env = node.env + secrets.resolve(node)
        files = ((node_env_file(where.layout, node.name), env_file_text(env), 0o600),) if env else ()
        return NodeRun(command=docker_run(node, plan=plan, spec=spec, where=where), check="any", files=files,
                       pre=_remove_first(where, container_name(plan.stack, node.name)))

    def prepare(self, run: Run, facts: Facts) -> list[str]:
        changes = []
        if run.spec.has_gpu and "nvidia" not in facts.flags:
            script = render("provision/nvidia_toolkit.sh.j2")
            run.host.put(script.encode(), f"{run.layout.tmp}/nvidia-toolkit.sh", mode=0o700)
            run.host.sudo(f"bash {q(run.layout.tmp + '/nvidia-toolkit.sh')}", timeout=900)
            changes.append("NVIDIA container toolkit")
        image, engine = ros_image(run.plan), run.engine
        for server, user, ref in run.plan.registries:
            # The password reaches the engine through a 0600 file on the host, removed at once: never a
            # command line, the plan or a log.
            path = f"{run.layout.tmp}/registry-{server.replace(':', '-')}"
            run.host.put(secrets.read(ref).encode(), path, mode=0o600)
            done = run.host.run(f"{engine} login {q(server)} --username {q(user)} --password-stdin < {q(path)}; "
                                f"status=$?; rm -f {q(path)}; exit $status", check=False, timeout=120)
            if not done.ok:
                raise ProvisionError(f"{run.spec.name}: {engine} login to {server} as {user} failed "
                                     f"({done.last_line()})")
            changes.append(f"logged in to {server}")
        if not run.host.run(f"{engine} image inspect {q(image)} >/dev/null 2>&1", check=False).ok:
            run.host.run(f"{engine} pull -q {q(image)}", timeout=900)
            changes.append(f"pulled {image}")
        return changes + _middleware_image(run, image)

    def build_images(self, run: Run) -> StepResult:
        """Build each workload or ``build:`` node's image on the host, unless its digest is there already."""
        host, engine, layout = run.host, run.engine, run.layout
        base = run.ros_image or images.base_image(run.plan)
        base_id = host.run(f"{engine} image inspect --format '{{{{.Id}}}}' {q(base)}").stdout.strip()
        flavour, built = "", []
        with tempfile.TemporaryDirectory(prefix="fogiac-build-") as tmp:
            for node in (run.plan.node(n) for n in run.spec.nodes):
                if not images.needs_image(node):
                    continue
                if node.workload is not None:
                    flavour = flavour or host.run(f"{engine} run --rm --network none -- {q(base)} "
                                                  "sh -c '. /etc/os-release && echo $ID'").stdout.strip()
                    recipe = images.workload_context(node, flavour=flavour, into=Path(tmp) / node.name)
                elif node.launch is not None:
                    recipe = images.launch_context(node, plan=run.plan, into=Path(tmp) / node.name, base=base)
                else:
                    recipe = images.user_context(node, stack=run.plan.stack)
                done = images.build(host, recipe, engine=engine, base_id=base_id, dest=f"{layout.build}/{node.name}",
                                    tmp_dir=layout.tmp, log=f"{layout.build}/{node.name}.log",
                                    pip=run.facts.pip if run.facts is not None else None,
                                    user=node.build is not None)
                run.images[node.name] = done.tag
                if done.built:
                    built.append(f"{node.name} ({done.tag})")
        return (CHANGED, f"built {', '.join(built)}") if built else (OK, f"{len(run.images)} image(s) up to date")

    def set_up_workspace(self, run: Run, *, local: str, dest: str, bodies: list[bytes]) -> None:
        names = tuple(f"{i}.sh" for i in range(len(bodies)))
        for name, body in zip(names, bodies, strict=True):
            run.host.put(body, f"{dest}/.fogiac-setup/{name}", mode=0o700)
        log = f"{run.layout.build}/ws-{dest.rsplit('/', 1)[-1]}.log"
        built = run.host.run(f"mkdir -p {q(run.layout.build)} && "
                             f"{workspace_build_command(run.plan, run.where(), local, names)} >{q(log)} 2>&1",
                             check=False, timeout=1800)
        if not built.ok:
            tail = run.host.run(f"tail -n 1 {q(log)}", check=False).last_line()
            raise ProvisionError(f"{run.spec.name}: workspace {Path(local).name}: build in "
                                 f"{node_image(run.plan, run.where())} failed ({tail}); log: {log}")

    def env_setup(self, native: NativeRos) -> str:
        return ""  # the ROS image's entrypoint sources its own


def _middleware_image(run: Run, image: str) -> list[str]:
    """The ROS image with what the middleware's nodes need (rmw_zenoh_cpp): the image itself when it has
    it, else one built over it on the host. Remembered per base image id, so an unchanged base costs no
    container run on the next ``up``."""
    native = run.native_ros
    if not native.image_layer:
        return []
    host, engine = run.host, run.engine
    base_id = host.run(f"{engine} image inspect --format '{{{{.Id}}}}' {q(image)}").stdout.strip()
    marker = f"{run.layout.state}/ros-image.sha256"
    known = (run.facts.marker(marker) if run.facts is not None else "").split()
    if len(known) == 2 and known[0] == base_id and host.run(f"{engine} image inspect {q(known[1])} >/dev/null 2>&1",
                                                           check=False).ok:
        run.ros_image = known[1]
        return []
    changes = []
    if host.run(f"{engine} run --rm --network none -- {q(image)} {native.check}", check=False).ok:
        run.ros_image = image
    else:
        with tempfile.TemporaryDirectory(prefix="fogiac-ros-image-") as tmp:
            (Path(tmp) / "Dockerfile").write_text(f"FROM {image}\n{native.image_layer}\n")
            recipe = images.Recipe(node=f"the ROS image ({', '.join(native.packages[1:])})",
                                   repo=f"fogiac/ros-{run.plan.ros_distro}", context=Path(tmp), dockerfile="Dockerfile")
            done = images.build(host, recipe, engine=engine, base_id=base_id, dest=f"{run.layout.build}/ros-image",
                                tmp_dir=run.layout.tmp, log=f"{run.layout.build}/ros-image.log")
        run.ros_image = done.tag
        changes.append(f"built {done.tag}")
    host.put(f"{base_id} {run.ros_image}\n".encode(), marker, mode=0o600)
    return changes


CONTAINER = ContainerRuntime()
