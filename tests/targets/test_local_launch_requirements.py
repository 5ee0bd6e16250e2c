"""A launch package's own Python requirements on the local target's native runtime.

The node's script starts with ``#!/usr/bin/env python3`` and imports a package that neither the
system's python3 nor fogiac's own environment has; provisioning installs it in the sandbox's venv
(the venv's bin leads the node's PATH), the node publishes through the relay to a robot-side
roscore, and a second ``up`` installs nothing.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.procs import free_port
from tests.provision.conftest import make_workspace

PACKAGE = "anytree"


def _why_not() -> str | None:
    if shutil.which("roscore") is None:
        return "needs Debian's ros-core (roscore)"
    for python in ("/usr/bin/python3", sys.executable):
        if subprocess.run([python, "-c", f"import {PACKAGE}"], capture_output=True).returncode == 0:
            return f"{python} has {PACKAGE} already: nothing would show the venv is used"
    return None


pytestmark = [pytest.mark.ros, pytest.mark.skipif(_why_not() is not None, reason=_why_not() or "")]

TALKER = f"""#!/usr/bin/env python3
import importlib.metadata
import {PACKAGE}  # noqa: F401 (the import is the point)
import rospy
from std_msgs.msg import String

rospy.init_node("fog_talker")
pub = rospy.Publisher("/chatter", String, queue_size=1)
rate = rospy.Rate(5)
while not rospy.is_shutdown():
    pub.publish("{PACKAGE} " + importlib.metadata.version("{PACKAGE}"))
    rate.sleep()
"""


def test_a_launch_packages_requirements_reach_its_native_node_once(tmp_path: Path, _state_dir: Path) -> None:
    ws = make_workspace(tmp_path / "ws")
    (ws / "src" / "fogtest" / "scripts" / "talker.py").write_text(TALKER)
    (tmp_path / "requirements.txt").write_text(f"{PACKAGE}==2.13.0\n")
    edge = free_port()
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(f"""name: launchreq
cloud: {{provider: local, runtime: native}}
edge: {{ros_master: "http://127.0.0.1:{edge}"}}
nodes:
  - name: talker
    machine: t3.small
    launch: {{package: fogtest, file: talker.launch, workspace: ws, requirements: requirements.txt}}
    topics: {{out: [/chatter]}}
""")
    runner = CliRunner()
    try:
        up = runner.invoke(app, ["up", str(manifest), "--yes", "--start-edge-master"])
        assert up.exit_code == 0, up.output
        env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{edge}", "ROS_HOSTNAME": "127.0.0.1"}
        echoed = subprocess.run(["rostopic", "echo", "-n", "1", "/chatter"], env=env, capture_output=True,
                                text=True, timeout=90).stdout
        assert echoed.startswith(f'data: "{PACKAGE} 2.13.0"'), echoed
        again = runner.invoke(app, ["up", str(manifest), "--yes"])
        assert again.exit_code == 0 and "no changes" in again.output, again.output
    finally:
        down = runner.invoke(app, ["down", str(manifest), "--yes"])
    assert down.exit_code == 0, down.output
