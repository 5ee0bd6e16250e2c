"""The SLAM node's container recipe: the template's defaults and one render call."""

from __future__ import annotations

from typing import Any

from workloads.recipe import render_dockerfile

TEMPLATE = "workloads/slam/Dockerfile.j2"

DEFAULTS: dict[str, Any] = {
    "base_image": "ubuntu:22.04",
    "apt_packages": ["python3", "python3-venv", "ros-core", "python3-rospy", "python3-std-msgs",
                     "python3-sensor-msgs", "python3-geometry-msgs"],
    # Pinned: the versions this workload was measured with (README.md); all ship manylinux wheels.
    "pip_packages": ["numpy>=1.24", "typer>=0.12", "opencv-python-headless==5.0.0.93", "gtsam==4.3.0"],
    "cores": 0,
    "mono": False,
    "features": 1000,
}


# Per base distribution (the /etc/os-release ID of the host's ROS base image): overrides of
# DEFAULTS. A ROS base from Debian's own packages (bookworm) has ros-core, rospy and std_msgs;
# the image and pose messages are added.
FLAVOURS: dict[str, dict[str, Any]] = {
    "ubuntu": {},
    "debian": {"base_image": "ros:noetic-ros-core",
               "apt_packages": ["python3-venv", "python3-sensor-msgs", "python3-geometry-msgs"]},
}


def requirements() -> list[str]:
    """What the node needs from PyPI beside the system's rospy: the recipe's own list."""
    return list(DEFAULTS["pip_packages"])


def dockerfile(**overrides: Any) -> str:
    """The Dockerfile text; ``overrides`` replace DEFAULTS, unknown names are an error."""
    return render_dockerfile(TEMPLATE, DEFAULTS, overrides)
