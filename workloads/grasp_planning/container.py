"""The grasp planner's container recipe: the template's defaults and one render call."""

from __future__ import annotations

from typing import Any

from workloads.recipe import render_dockerfile

TEMPLATE = "workloads/grasp_planning/Dockerfile.j2"

DEFAULTS: dict[str, Any] = {
    "base_image": "nvidia/cuda:12.8.1-runtime-ubuntu22.04",
    "torch_version": "2.13.0",
    "torch_index_url": "",
    "pip_packages": ["numpy>=1.24", "typer>=0.12"],
    "device": "auto",
    "threads": 0,
    "model": "/opt/fogiac/workloads/grasp_planning/model.pt",
}


# Per base distribution (the /etc/os-release ID of the base image): overrides of DEFAULTS.
FLAVOURS: dict[str, dict[str, Any]] = {"ubuntu": {}}


def requirements() -> list[str]:
    """What the node needs from PyPI beside the system's rospy: torch pinned, then the recipe's list."""
    return [f"torch=={DEFAULTS['torch_version']}", *DEFAULTS["pip_packages"]]


def dockerfile(**overrides: Any) -> str:
    """The Dockerfile text; ``overrides`` replace DEFAULTS, unknown names are an error."""
    return render_dockerfile(TEMPLATE, DEFAULTS, overrides)
