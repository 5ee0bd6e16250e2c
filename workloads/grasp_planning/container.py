"""The grasp planner's container recipe: the template's defaults and one render call."""

from __future__ import annotations

from typing import Any

from workloads.recipe import render_dockerfile

TEMPLATE = "workloads/grasp_planning/Dockerfile.j2"

DEFAULTS: dict[str, Any] = {
    "base_image": "nvidia/cuda:12.8.1-runtime-ubuntu22.04",
    "torch_version": "2.13.0",
    "torch_index_url": "",
    "apt_packages": ["python3", "python3-venv", "ros-core", "python3-rospy", "python3-std-msgs",
                     "python3-sensor-msgs", "python3-geometry-msgs"],
    "pip_packages": ["numpy>=1.24", "typer>=0.12"],
    "device": "auto",
    "threads": 0,
    "model": "/opt/fogiac/workloads/grasp_planning/model.pt",
}


# Per base distribution (the /etc/os-release ID of the host's ROS base image): overrides of
# DEFAULTS. A ROS base from Debian's own packages (bookworm, as the tests' base image) already
# has ROS, the message packages and python3-venv: it is the base, and torch runs on the CPU.
FLAVOURS: dict[str, dict[str, Any]] = {
    "ubuntu": {},
    "debian": {"base_image": "ros:noetic-ros-core", "apt_packages": [], "device": "cpu"},
}


def requirements() -> list[str]:
    """What the node needs from PyPI beside the system's rospy: torch pinned, then the recipe's list."""
    return [f"torch=={DEFAULTS['torch_version']}", *DEFAULTS["pip_packages"]]


def dockerfile(**overrides: Any) -> str:
    """The Dockerfile text; ``overrides`` replace DEFAULTS, unknown names are an error."""
    return render_dockerfile(TEMPLATE, DEFAULTS, overrides)
