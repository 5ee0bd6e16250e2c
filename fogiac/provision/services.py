"""What runs on a host, decided purely from the plan: the middleware's services (a ROS master, a router,
asked of it through :mod:`fogiac.net.middleware`), then one service per node.

Why pure: the exact ``docker run`` lines, service scripts and systemd units are what a reviewer
checks, and they must be testable on a machine without Docker or systemd. The steps in
:mod:`.steps` only compare these texts with what the host has and act on differences. The service
model itself (:class:`Layout`, :class:`Where`, :class:`Service`) is :mod:`fogiac.hostmodel`'s,
re-exported here; how a node runs is its runtime's (:mod:`.runtimes`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

from fogiac.errors import ProvisionError
from fogiac.hostmodel import Launching, make_service, node_instances
from fogiac.hostmodel import Layout as Layout
from fogiac.hostmodel import Service as Service
from fogiac.hostmodel import Where as Where
from fogiac.hostmodel import container_name as container_name
from fogiac.hostmodel import master_uri as master_uri
from fogiac.hostmodel import node_image as node_image
from fogiac.hostmodel import ros_image as ros_image
from fogiac.hostmodel import unit_name as unit_name
from fogiac.net import middleware
from fogiac.plan.model import HostSpec, NodeSpec, Plan
from fogiac.provision.host import q
from fogiac.provision.runtimes import CONTAINER as CONTAINER
from fogiac.provision.runtimes import NATIVE as NATIVE
from fogiac.provision.runtimes.container import docker_run as docker_run
from fogiac.provision.runtimes.container import env_file_text as env_file_text
from fogiac.provision.runtimes.container import ros_env as ros_env
from fogiac.provision.runtimes.container import workspace_build_command as workspace_build_command


def env_script(env: Mapping[str, str], *, host: str, setup: str = "") -> str:
    """The env file every service script on a host sources: the middleware's environment for nodes,
    after ``setup`` (the ROS installation's own script, when the host has it)."""
    first = f"if [ -f {q(setup)} ]; then . {q(setup)}; fi\n" if setup else ""
    return f"# fogiac: environment of the nodes on {host}. Source it: . ros.sh\n" + first + "".join(
        f"export {key}={q(value)}\n" for key, value in env.items())


def node_services(plan: Plan, spec: HostSpec, where: Where) -> tuple[Service, ...]:
    """One service per node placed on ``spec``, in plan order, started after the middleware's service
    (its master or router); a per-robot node one per robot it serves (``node-slam@arm1``), so a robot added or
    removed starts or stops its own instance only. Without a ROS master (ROS 2) a node's health is its process
    running: there is nothing to register with."""
    digests = dict(where.workspace_digests)
    chosen = middleware.get(plan.middleware)
    out = []
    for node in (each for name in spec.nodes for each in _instances(plan, plan.node(name), chosen.launching)):
        parts = where.runtime.node(node, plan, spec, where)
        notes: tuple[str, ...] = ()
        if node.launch is not None:
            notes = (f"workspace {node.launch.workspace} digest {digests.get(node.launch.workspace, 'unknown')}",)
        out.append(make_service(
            f"node-{node.name}", plan=plan, spec=spec, where=where, command=parts.command,
            check=parts.check if chosen.node_master else "alive",
            env=parts.env, pre=parts.pre, package_path=parts.package_path,
            python_path=parts.python_path, cwd=parts.cwd, notes=notes, after=chosen.nodes_after,
            files=parts.files, bin_path=parts.bin_path,
        ))
    return tuple(out)



def _instances(plan: Plan, node: NodeSpec, launching: Launching) -> tuple[NodeSpec, ...]:
    """``node`` as it runs: itself, or for ``serve: per_robot`` one copy per robot, named ``slam@arm1``, whose
    command carries the ROS generation's arguments that put it in the robot's namespace (validate lets only a
    command node with listed topics, on a generation that has such arguments, be per-robot)."""
    if not node.per_robot:
        return (node,)
    if launching.instance_args is None or node.kind != "command":
        raise ProvisionError(f"node {node.name}: serve: per_robot runs a command: node, on a middleware whose "
                             "nodes take a robot's namespace as arguments (the relay's ROS 1, Zenoh's ROS 2)")
    topics = (*node.topics_in, *node.topics_out)
    return tuple(dataclasses.replace(node, name=instance, command=node.command + launching.instance_args(robot, topics))
                 for robot, instance in zip(plan.robots_of(node), node_instances(plan, node), strict=True))
