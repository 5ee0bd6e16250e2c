"""A ``launch:`` node the way its ROS generation runs it, checked on the exact text: ROS 1 builds with
catkin_make and runs ``roslaunch --wait`` (tests/provision/test_services.py pins that path); ROS 2
builds with colcon, sources its install/ overlay and runs ``ros2 launch``."""

from __future__ import annotations

import shlex
import subprocess
from pathlib import Path

import pytest

from fogiac.manifest.schema import parse_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.model import Plan
from fogiac.provision import services as svc
from tests.support.ros2 import standin_ros2

MANIFEST = """
name: fleet
ros: {distro: jazzy}
cloud: {provider: aws, region: us-west-2}
edge: {zenoh_router: "tcp/192.0.2.7:7447"}
nodes:
  - name: arm
    machine: t3.small
    launch: {package: fogtest, file: talker.launch.py, workspace: ws}
    topics: {out: [/chatter]}
"""
BASE = "/home/ubuntu/.fogiac/fleet-dev/x"


@pytest.fixture
def plan(tmp_path: Path) -> Plan:
    (tmp_path / "ws").mkdir()
    return compile_plan(parse_manifest(MANIFEST, base=tmp_path))


def _where(runtime: str) -> svc.Where:
    return svc.Where(layout=svc.Layout(BASE), runtime=runtime, master_port=11311, relay_port=11411,
                     ros_address="10.10.0.5", python="python3", code_root=f"{BASE}/lib", user="ubuntu")


def test_a_native_ros2_launch_node_sources_its_colcon_overlay_and_runs_ros2_launch(plan: Plan) -> None:
    where = _where(svc.NATIVE)
    ws = where.layout.workspace(plan.node("arm").launch.workspace)  # type: ignore[union-attr]
    (arm,) = svc.node_services(plan, plan.host("arm"), where)
    lines = arm.script.splitlines()
    assert lines[-3:] == [
        f"cd {ws}",
        f"if [ -f {ws}/install/setup.bash ]; then . {ws}/install/setup.bash; fi",
        "exec ros2 launch fogtest talker.launch.py",
    ]
    # after the distro's setup.bash and the middleware's environment, which the env file holds
    assert lines.index(f". {BASE}/env/ros.sh") < lines.index(f"cd {ws}")
    assert "ROS_PACKAGE_PATH" not in arm.script  # a ROS 1 variable
    assert arm.check == "alive"  # no master to register with


def test_a_container_ros2_launch_node_sources_its_overlay_in_the_mounted_workspace(plan: Plan) -> None:
    where = _where(svc.CONTAINER)
    ws = where.layout.workspace(plan.node("arm").launch.workspace)  # type: ignore[union-attr]
    line = svc.docker_run(plan.node("arm"), plan=plan, spec=plan.host("arm"), where=where)
    assert line.endswith(
        f"--volume {ws}:/fogiac/ws:ro --workdir /fogiac/ws -- ros:jazzy-ros-core bash -c "
        "'if [ -f /fogiac/ws/install/setup.bash ]; then . /fogiac/ws/install/setup.bash; fi; "
        "exec ros2 launch \"$0\" \"$1\"' fogtest talker.launch.py"
    )
    assert "ROS_PACKAGE_PATH" not in line and "--env RMW_IMPLEMENTATION=rmw_zenoh_cpp" in line


def test_a_ros2_workspace_builds_with_colcon_in_the_ros_image_and_an_image_without_colcon_fails_in_one_line(
        plan: Plan, tmp_path: Path) -> None:
    where = _where(svc.CONTAINER)
    ws = where.layout.workspace("ws")
    line = svc.workspace_build_command(plan, where, "ws", ("0.sh",))
    prefix = (f"docker run --rm --network host --volume {ws}:/fogiac/ws --workdir /fogiac/ws -- ros:jazzy-ros-core "
              "bash -ec ")
    assert line.startswith(prefix)
    script = shlex.split(line[len(prefix):])[0].replace(". /fogiac/ws/.fogiac-setup/0.sh; ", "")
    work = tmp_path / "work"
    (work / "src" / "fogtest").mkdir(parents=True)
    (work / "src" / "fogtest" / "package.xml").write_text("<package><name>fogtest</name></package>\n")
    bare = {"PATH": "/usr/bin:/bin"}  # an image without colcon
    done = subprocess.run(["bash", "-ec", script], cwd=work, env=bare, capture_output=True, text=True, check=False)
    assert done.returncode == 1
    assert done.stderr == ("the ROS image has no colcon to build this workspace's packages; "
                           "use an image that has it (a ros-base image)\n")
    tools = standin_ros2(tmp_path / "ros")  # an image with colcon builds, quietly
    done = subprocess.run(["bash", "-ec", script], cwd=work, env={"PATH": f"{tools}:/usr/bin:/bin"},
                          capture_output=True, text=True, check=False)
    assert (done.returncode, done.stderr) == (0, "")
    assert (work / "install" / "share" / "fogtest" / "package.xml").is_file()
    (work / "src" / "fogtest" / "package.xml").unlink()  # no packages: nothing to build, no colcon needed
    assert subprocess.run(["bash", "-ec", script], cwd=work, env=bare, check=False).returncode == 0


def test_a_ros1_workspace_still_builds_with_catkin_make(tmp_path: Path) -> None:
    (tmp_path / "ws").mkdir()
    noetic = compile_plan(parse_manifest(MANIFEST.replace("jazzy", "noetic").replace(
        'edge: {zenoh_router: "tcp/192.0.2.7:7447"}', "edge: {ros_master: http://192.0.2.7:11311}"), base=tmp_path))
    where = _where(svc.CONTAINER)
    assert svc.workspace_build_command(noetic, where, "ws", ()).endswith(
        "-- ros:noetic-ros-core bash -ec 'if [ -f src/CMakeLists.txt ]; then catkin_make >/dev/null; fi'")
