"""The motion planner's container recipe: the template's defaults and one render call."""

from __future__ import annotations

from typing import Any

from workloads.recipe import render_dockerfile

TEMPLATE = "workloads/motion_planning/Dockerfile.j2"

DEFAULTS: dict[str, Any] = {
    "ros_distro": "noetic",
    "python": "python3.9",
    "apt_packages": ["python3.9", "python3.9-venv", "ros-noetic-geometry-msgs", "ros-noetic-std-msgs"],
    "pip_packages": ["ompl==2.0.1", "python-fcl>=0.7", "trimesh>=4", "numpy>=1.24", "pycollada>=0.8"],
    "cores": 0,
    "time_limit": 0,
    "planner": "rrtconnect",
}


# What differs on a base whose ROS comes from Debian's own packages (bookworm: Python 3.11,
# rospy and the message packages already installed, as in the test base image).
FLAVOURS: dict[str, dict[str, Any]] = {
    "ubuntu": {},
    "debian": {"python": "python3", "apt_packages": []},
}


def requirements() -> list[str]:
    """What the node needs from PyPI beside the system's rospy: the recipe's own list."""
    return list(DEFAULTS["pip_packages"])


def dockerfile(**overrides: Any) -> str:
    """The Dockerfile text; ``overrides`` replace DEFAULTS, unknown names are an error."""
    return render_dockerfile(TEMPLATE, DEFAULTS, overrides)
