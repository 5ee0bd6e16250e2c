"""The container recipe renders (StrictUndefined) into a Dockerfile that runs the node."""

from __future__ import annotations

import json

import jinja2
import pytest

from fogiac.errors import WorkloadError
from fogiac.render import render
from workloads.motion_planning.container import TEMPLATE, dockerfile


def test_default_recipe() -> None:
    text = dockerfile()
    lines = text.splitlines()
    assert lines[0] == "FROM ros:noetic-ros-core"
    assert " ompl==2.0.1 " in text and "python3.9 -m venv --system-site-packages /opt/venv" in text
    assert "COPY workloads/motion_planning/ workloads/motion_planning/" in lines
    assert "\nWORKDIR /opt/fogiac\n" in text
    cmd = json.loads(lines[-1].removeprefix("CMD "))
    assert "    PATH=/opt/venv/bin:$PATH \\" in lines  # `python` is the venv's, for fogiac's docker run command
    assert cmd == ["python", "-m", "workloads.motion_planning", "node",
                   "_cores:=0", "_time_limit:=0", "_planner:=rrtconnect"]


def test_overrides_and_quoting() -> None:
    text = dockerfile(cores=96, time_limit=30, pip_packages=["ompl==2.0.1", "numpy<2; python_version<'3.10'"])
    assert "'numpy<2; python_version<'\"'\"'3.10'\"'\"''" in text
    assert json.loads(text.splitlines()[-1].removeprefix("CMD "))[4:6] == ["_cores:=96", "_time_limit:=30"]


def test_unknown_and_missing_variables() -> None:
    valid = "apt_packages, cores, pip_packages, planner, python, ros_distro, time_limit"
    with pytest.raises(WorkloadError, match=rf"^unknown Dockerfile variables gpus; valid: {valid}$"):
        dockerfile(gpus=True)
    with pytest.raises(jinja2.UndefinedError, match="'ros_distro' is undefined"):
        render(TEMPLATE)
