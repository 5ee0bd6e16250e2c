"""The SLAM node's container recipe: defaults, flavours, and unknown variables refused."""

from __future__ import annotations

import pytest

from fogiac.errors import WorkloadError
from workloads.slam.container import DEFAULTS, FLAVOURS, dockerfile, requirements


def test_recipe_installs_the_pinned_libraries_and_runs_the_node() -> None:
    text = dockerfile()
    assert text.startswith("FROM ubuntu:22.04")
    assert "opencv-python-headless==5.0.0.93" in text and "gtsam==4.3.0" in text
    assert "COPY workloads/slam/ workloads/slam/" in text
    assert text.rstrip().endswith('CMD ["python", "-m", "workloads.slam", "node", "_cores:=0", "_mono:=false", '
                                  '"_features:=1000"]')


def test_debian_flavour_builds_on_the_ros_base() -> None:
    text = dockerfile(**FLAVOURS["debian"])
    assert text.startswith("FROM ros:noetic-ros-core")
    (install,) = [line for line in text.splitlines() if "apt-get install" in line]
    assert install.split("--no-install-recommends")[1].split()[:-1] == ["python3-venv", "python3-sensor-msgs",
                                                                        "python3-geometry-msgs"]


def test_overrides_reach_the_node_and_unknown_names_are_refused() -> None:
    assert '"_cores:=8", "_mono:=true"' in dockerfile(cores=8, mono=True)
    with pytest.raises(WorkloadError, match="unknown Dockerfile variables corez; valid: apt_packages, base_image"):
        dockerfile(corez=8)


def test_requirements_are_the_recipes_pip_list() -> None:
    assert requirements() == DEFAULTS["pip_packages"]
