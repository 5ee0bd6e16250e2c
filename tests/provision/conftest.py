"""Fixtures for provisioning tests: a tiny catkin-free ROS workspace and manifests using it."""

from __future__ import annotations

import shutil
import sys
from functools import cache
from pathlib import Path

import pytest

PACKAGE_XML = """<?xml version="1.0"?>
<package format="2">
  <name>fogtest</name><version>0.0.1</version><description>fogiac test node</description>
  <maintainer email="test@example.com">test</maintainer><license>MIT</license>
</package>
"""

TALKER = """#!/usr/bin/python3
import rospy
from std_msgs.msg import String

rospy.init_node("fog_talker")
pub = rospy.Publisher("/chatter", String, queue_size=1)
rate = rospy.Rate(2)
while not rospy.is_shutdown():
    pub.publish("hello from the fog")
    rate.sleep()
"""

# required="true": when the node dies roslaunch exits, and fogiac's supervisor restarts it.
LAUNCH = """<launch>
  <node name="fog_talker" pkg="fogtest" type="talker.py" output="screen" required="true"/>
</launch>
"""


@cache  # asked at collection by many modules, in every pytest-xdist worker; each probe starts a Python
def ros_skip_reason() -> str | None:
    if shutil.which("roscore") is None or shutil.which("roslaunch") is None:
        return "needs Debian's ros-core (roscore, roslaunch)"
    import subprocess

    if subprocess.run(["/usr/bin/python3", "-c", "import rospy, std_msgs"], capture_output=True).returncode:
        return "needs python3-rospy and python3-std-msgs for /usr/bin/python3"
    return None


def make_workspace(root: Path, *, extra_files: int = 0) -> Path:
    """A workspace with one package ``fogtest`` (talker.py + talker.launch) and ignorable junk."""
    pkg = root / "src" / "fogtest"
    (pkg / "scripts").mkdir(parents=True)
    (pkg / "launch").mkdir()
    (pkg / "package.xml").write_text(PACKAGE_XML)
    talker = pkg / "scripts" / "talker.py"
    talker.write_text(TALKER)
    talker.chmod(0o755)
    (pkg / "launch" / "talker.launch").write_text(LAUNCH)
    config = pkg / "config"
    config.mkdir()
    for i in range(extra_files):
        (config / f"params_{i:03d}.yaml").write_text("".join(f"gain_{j}: {i * 1000 + j}.{j:04d}\n" for j in range(200)))
    for junk in ("build", "devel", ".git", "src/fogtest/__pycache__"):
        (root / junk).mkdir(parents=True, exist_ok=True)
        (root / junk / "big.bin").write_bytes(b"\0" * 4096)
    (root / "notes.tmp").write_text("scratch\n")
    (root / ".fogiacignore").write_text("# local scratch files\n*.tmp\n")
    return root


def hosts_manifest(path: Path, *, hosts: list[tuple[str, str]], key: Path, workspace: Path, name: str = "labtest",
                   gpus: int = 0) -> Path:
    """A ``hosts`` manifest: one launch node per host, pinned to it."""
    lines = [f"name: {name}", "cloud:", "  provider: hosts", "  hosts:"]
    for host, address in hosts:
        lines += [f"    - name: {host}", f"      address: {address}", "      user: root", f"      key: {key}",
                  f"      gpus: {gpus}"]
    lines.append("nodes:")
    for host, _ in hosts:
        lines += [f"  - name: talker-{host}", "    machine: t3.small", f"    host: {host}",
                  f"    launch: {{package: fogtest, file: talker.launch, workspace: {workspace}}}"]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture
def python() -> str:
    return sys.executable
