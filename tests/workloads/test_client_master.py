"""Issue 35, item 18: the motion planner's robot-side client talks to the manifest's ``edge.ros_master`` (or
``--master``), not only ``ROS_MASTER_URI``, and when no master answers there it says so in one line within
its timeout (it used to retry "Unable to register with master node" for ever)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from fogiac.procs import free_port
from tests.conftest import REPO
from workloads import master

pytest.importorskip("rospy")


def client(cwd: Path, *args: str, env_master: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])),
           "ROS_MASTER_URI": env_master}
    return subprocess.run([sys.executable, "-m", "workloads.motion_planning", "client", "easy", *args], cwd=cwd,
                          env=env, capture_output=True, text=True, timeout=120, check=False)


def test_the_manifests_master_is_taken_and_its_silence_is_one_line(tmp_path: Path) -> None:
    edge = f"http://127.0.0.1:{free_port()}"
    (tmp_path / "fogiac.yaml").write_text(f"name: x\nedge:\n  ros_master: {edge}\nnodes: []\n")
    done = client(tmp_path, "--master-timeout", "1", env_master=f"http://127.0.0.1:{free_port()}")
    assert done.returncode == 1
    assert done.stderr == (f"error: no ROS master answers at {edge} (from fogiac.yaml's edge.ros_master) within 1 s: "
                           "start the robot's roscore (or fogiac up --start-edge-master), or pass --master URI\n")


def test_master_overrides_the_manifest(tmp_path: Path) -> None:
    given = f"http://127.0.0.1:{free_port()}"
    (tmp_path / "fogiac.yaml").write_text("edge: {ros_master: http://127.0.0.1:1}\n")
    done = client(tmp_path, "--master", given, "--master-timeout", "1", env_master="http://127.0.0.1:2")
    assert done.returncode == 1 and f"at {given} (from --master)" in done.stderr and done.stderr.count("\n") == 1


def test_without_a_manifest_the_environment_decides(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("ROS_MASTER_URI", "http://127.0.0.1:3")
    assert master.choose(None, None) == ("http://127.0.0.1:3", "ROS_MASTER_URI")
