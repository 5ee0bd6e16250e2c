"""The protocol every node runtime answers, and what it may ask of the host being provisioned.

A runtime is how a host runs ROS: ``container`` (the ROS image and the nodes' images, under docker or
podman) or ``native`` (the host's own ROS, fogiac's code in a venv). It is chosen once per host
(:func:`fogiac.provision.runtimes.choose`); the steps and services ask it, never test its name.
"""

from __future__ import annotations

from typing import Protocol

from fogiac.hostmodel import Launching, Layout, NativeRos, Runtime, Where
from fogiac.plan.model import HostSpec, Plan
from fogiac.provision.host import Host, q
from fogiac.provision.probe import Facts

CHANGED, OK, SKIPPED = "changed", "ok", "skipped"
StepResult = tuple[str, str]  # (CHANGED | OK | SKIPPED, detail)


class Run(Protocol):
    """What a runtime reads and learns about one host's provisioning (``fogiac.provision.steps.HostRun``)."""

    plan: Plan
    spec: HostSpec
    host: Host
    engine: str  # the container engine's command (container runtime), learnt by prepare
    ros_image: str  # the ROS image with what the middleware needs, when the plan's lacks it
    facts: Facts | None
    images: dict[str, str]  # node -> image tag built on the host

    @property
    def layout(self) -> Layout: ...

    @property
    def allow_install(self) -> bool: ...  # the caller lets fogiac install system packages

    @property
    def native_ros(self) -> NativeRos: ...  # what the middleware's nodes need of ROS on the host

    @property
    def launching(self) -> Launching: ...  # how the ROS generation builds and launches

    def where(self) -> Where: ...

    def env_text(self) -> str: ...  # the nodes' env file as the services step writes it


class HostRuntime(Runtime, Protocol):
    """A runtime as provisioning sees it: the services' half (:class:`fogiac.hostmodel.Runtime`) plus
    what it does to the host before the services start."""

    @property
    def nodes_on_host(self) -> bool: ...  # True: nodes run from the host's python, their requirements in its venv

    def prepare(self, run: Run, facts: Facts) -> list[str]:
        """Give the host what running ROS this way needs (an image pulled, packages installed); what changed."""
        ...

    def build_images(self, run: Run) -> StepResult:
        """Build the nodes' images on the host, where this runtime has images."""
        ...

    def set_up_workspace(self, run: Run, *, local: str, dest: str, bodies: list[bytes]) -> None:
        """Run a pushed workspace's env scripts (``bodies``) and its build, where its nodes will run."""
        ...

    def env_setup(self, native: NativeRos) -> str:
        """The ROS installation's setup script the nodes' env file sources first ('' : none)."""
        ...


def source_overlay(ws: str, overlay: str) -> str:
    """Source what the workspace's build left (catkin's devel/, colcon's install/), when it built."""
    setup = q(f"{ws}/{overlay}")
    return f"if [ -f {setup} ]; then . {setup}; fi"
