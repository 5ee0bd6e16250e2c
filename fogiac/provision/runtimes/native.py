"""The native runtime: nodes run from the host's own ROS and fogiac's venv, each under its service."""

from __future__ import annotations

from dataclasses import dataclass

from fogiac.errors import ProvisionError
from fogiac.hostmodel import NativeRos, NodeRun, Where
from fogiac.net import middleware
from fogiac.plan.model import HostSpec, NodeSpec, Plan
from fogiac.provision import workload
from fogiac.provision.host import q
from fogiac.provision.probe import Facts
from fogiac.provision.runtimes.base import SKIPPED, Run, StepResult, source_overlay


@dataclass(frozen=True)
class NativeRuntime:
    name: str = "native"
    nodes_on_host: bool = True

    def program(self, plan: Plan, spec: HostSpec, where: Where, *, name: str, argv: tuple[str, ...],
                env: tuple[tuple[str, str], ...]) -> tuple[str, tuple[str, ...]]:
        return " ".join(argv), ()

    def node(self, node: NodeSpec, plan: Plan, spec: HostSpec, where: Where) -> NodeRun:
        if node.kind == "image":
            raise ProvisionError(
                f"{spec.name}: node {node.name} runs image {node.image} but the host has no working "
                "container engine (`docker info` failed); set cloud.runtime: container to use podman there, "
                "install Docker, or use a launch/workload node"
            )
        if node.kind == "command":
            return NodeRun(command=" ".join(q(arg) for arg in node.command), check="alive", env=node.env)
        if node.kind == "launch" and node.launch is not None:
            ws = where.layout.workspace(node.launch.workspace)
            launching = middleware.get(plan.middleware).launching
            # ROS 1 finds the package through ROS_PACKAGE_PATH; ROS 2 through its build's overlay, sourced
            # over the distro's setup.bash (the env file) and the env scripts' build.
            # A node script run by `#!/usr/bin/env python3` (ROS's convention) finds the venv's python first.
            return NodeRun(command=" ".join((*launching.command, q(node.launch.package), q(node.launch.file))),
                           package_path=f"{ws}/src:{ws}" if launching.package_path else "", check="node", cwd=ws,
                           pre=() if launching.package_path else (source_overlay(ws, launching.overlay),),
                           bin_path=where.launch_bin if node.launch.requirements else "", env=node.env)
        python = where.workload_python or where.python
        package = workload.package(node.workload or "")
        return NodeRun(command=f"{q(python)} -m {package} node", python_path=where.code_root, check="node",
                       env=node.env)

    def prepare(self, run: Run, facts: Facts) -> list[str]:
        """What the plan's middleware needs on the host (ROS 1's roscore and rospy; ROS 2's setup.bash, ros2
        and rmw_zenoh_cpp): there already, installed when allowed, else one line saying what to install."""
        native = run.native_ros
        if native.probed and set(native.probed) <= facts.flags:
            return []
        if run.host.run(native.check, check=False).ok:
            return []
        if not run.allow_install:
            raise ProvisionError(
                f"{run.spec.name}: no ROS {run.plan.ros_distro} ({native.needs}) and no container engine; install "
                f"{' '.join(native.packages)}{' from ' + native.origin if native.origin else ''} with "
                f"`{native.by_hand}`, or let fogiac install them (`fogiac provision --allow-install`)")
        run.host.put(native.install.encode(), f"{run.layout.tmp}/ros-native.sh", mode=0o700)
        run.host.sudo(f"bash {q(run.layout.tmp + '/ros-native.sh')}", timeout=1800)
        return ["installed ROS packages"]

    def build_images(self, run: Run) -> StepResult:
        return SKIPPED, "native runtime: nodes run from the pushed code"

    def set_up_workspace(self, run: Run, *, local: str, dest: str, bodies: list[bytes]) -> None:
        # The nodes' env file as the services step will write it: on a first run it is not there yet.
        env = f"{run.layout.tmp}/ros-env.sh"
        run.host.put(run.env_text().encode(), env, mode=0o600)
        for i, body in enumerate(bodies):
            path = f"{run.layout.tmp}/setup-{i}.sh"
            run.host.put(body, path, mode=0o700)
            run.host.run(f"cd {q(dest)} && . {q(env)} && bash {q(path)}", timeout=1800)
        run.host.run(f"cd {q(dest)} && {run.launching.build_native(q(env))}", timeout=1800)

    def env_setup(self, native: NativeRos) -> str:
        return native.setup


NATIVE = NativeRuntime()
