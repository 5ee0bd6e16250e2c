"""What a ROS 2 plan asks of a native host: ros2 and rmw_zenoh_cpp, not ROS 1's roscore and rospy.

This machine has ROS 1 (Debian's roscore and rospy) and no ROS 2, so it shows both halves at
once: a ROS 2 plan on its sandbox is refused in one line naming packages.ros.org's packages and
the command (before, roscore alone let it through, and a real rmw_zenoh node would then have had
no ROS 2 to run on), while the same host with ROS 2 in its login environment provisions. The
installer script cannot run here (packages.ros.org serves Ubuntu, and there is no route to it):
its rendering is checked, and on this Debian it stops before touching apt.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.net import middleware
from fogiac.procs import free_port
from fogiac.provision import services as svc
from tests.support.ros2 import standin_ros2

REFUSAL = (r"^error: detector: no ROS jazzy \(/opt/ros/jazzy/setup\.bash or ros2 on PATH, rmw_zenoh_cpp\) and no "
           r"container engine; install ros-jazzy-ros-base ros-jazzy-rmw-zenoh-cpp from packages\.ros\.org \(apt "
           r"source: docs\.ros\.org/en/jazzy/Installation/Ubuntu-Install-Debs\.html\) with `sudo apt-get install -y "
           r"ros-jazzy-ros-base ros-jazzy-rmw-zenoh-cpp`, or let fogiac install them "
           r"\(`fogiac provision --allow-install`\)$")


def _why_not() -> str | None:
    if shutil.which("ros2") or Path("/opt/ros/jazzy/setup.bash").exists():
        return "this machine has ROS 2 jazzy: nothing to refuse"
    if shutil.which("roscore") is None:
        return "needs Debian's ros-core: the point is that roscore no longer lets a ROS 2 plan through"
    return None


def _manifest(path: Path) -> Path:
    path.write_text(f"""name: ros2-deps
ros: {{distro: jazzy}}
cloud: {{provider: local, runtime: native}}
edge: {{zenoh_router: "tcp/127.0.0.1:{free_port()}"}}
nodes:
  - {{name: detector, machine: t3.micro, command: [sleep, "3600"], topics: {{out: [/detections]}}}}
""")
    return path


@pytest.mark.skipif(_why_not() is not None, reason=_why_not() or "")
def test_a_ros2_plan_on_a_host_with_only_ros1_is_refused_in_one_line_and_provisions_with_ros2(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("zenoh", reason="needs eclipse-zenoh for the sandbox's router")
    manifest = _manifest(tmp_path / "fogiac.yaml")
    runner = CliRunner()
    try:
        up = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes"])
        assert up.exit_code == 1, up.output
        errors = [line for line in up.output.splitlines() if line.startswith("error:")]
        assert len(errors) == 1 and re.match(REFUSAL, errors[0].split(" (the other hosts")[0]), up.output
        assert "roscore" not in errors[0] and "Traceback" not in up.output

        monkeypatch.setenv("PATH", f"{standin_ros2(tmp_path / 'ros2')}:{os.environ['PATH']}")
        again = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes"])
        assert again.exit_code == 0, again.output
    finally:
        down = runner.invoke(app, ["down", str(manifest), "--target", "local", "--yes"])
    assert down.exit_code == 0, down.output


def test_a_ros2_host_needs_ros2_and_rmw_zenoh_and_the_nodes_source_its_setup() -> None:
    zenoh = middleware.deployment("zenoh").native_ros("kilted")
    assert zenoh.packages == ("ros-kilted-ros-base", "ros-kilted-rmw-zenoh-cpp")
    assert "roscore" not in zenoh.check and "rospy" not in zenoh.check and zenoh.probed == ()
    assert "ros2 pkg prefix rmw_zenoh_cpp" in zenoh.check
    env = svc.env_script({"RMW_IMPLEMENTATION": "rmw_zenoh_cpp"}, host="h", setup=zenoh.setup)
    assert env.splitlines()[1:] == ["if [ -f /opt/ros/kilted/setup.bash ]; then . /opt/ros/kilted/setup.bash; fi",
                                    "export RMW_IMPLEMENTATION=rmw_zenoh_cpp"]
    relay = middleware.deployment("relay").native_ros("noetic")
    assert relay.packages == ("ros-core", "python3-rospy", "python3-std-msgs") and relay.setup == ""


def test_the_ros2_installer_adds_packages_ros_org_and_installs_the_distros_packages(tmp_path: Path) -> None:
    script = middleware.deployment("zenoh").native_ros("jazzy").install
    path = tmp_path / "ros2-native.sh"
    path.write_text(script)
    assert subprocess.run(["bash", "-n", str(path)]).returncode == 0
    assert "ros-infrastructure/ros-apt-source/releases" in script and "ros2-apt-source_${version}.${codename}" in script
    assert 'grep -rqs "packages.ros.org/ros2"' in script  # the apt source is added once
    assert script.rstrip().endswith("apt-get install -y -q ros-jazzy-ros-base ros-jazzy-rmw-zenoh-cpp")
    release = Path("/etc/os-release").read_text()
    if "UBUNTU_CODENAME" in release:
        return  # on Ubuntu it would go on to apt: not run here
    # On a system packages.ros.org does not serve, it stops at once, in one line, with apt untouched.
    done = subprocess.run(["bash", str(path)], capture_output=True, text=True, timeout=30, env={"PATH": os.defpath})
    assert done.returncode == 1 and done.stdout == ""
    assert re.fullmatch(r"ROS 2 jazzy packages \(ros-jazzy-ros-base ros-jazzy-rmw-zenoh-cpp\) come from "
                        r"packages\.ros\.org for Ubuntu; this host runs .+\n", done.stderr), done.stderr
