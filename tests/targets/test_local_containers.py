"""The container runtime end to end in a real OCI engine (podman with runc), on the local target.

Each node runs in a container on the host network beside its sandbox's master container; the
edge relay carries its topic to a robot-side roscore started by fogiac. Covered: an ``image:``
node, a ``build:`` node (its image built on the host from a Dockerfile, its env through a 0600
file, rebuilt alone when one of its files changes), a
``launch:`` node (a catkin package built inside the ROS image, its env script sourced there, its
Python requirements in an image of its own), a
second stack beside the first, a no-change ``up``, loopback-only sockets, and ``down`` leaving no
container. The base image comes from ``.ci/containers.sh``.
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
from fogiac.errors import ProvisionError
from fogiac.procs import free_port
from fogiac.provision import images
from fogiac.provision.local import LocalHost
from tests.conftest import EXAMPLES
from tests.support.podman import podman_missing
from tests.targets.test_local import ask_planner

BASE = "docker.io/library/ros:noetic-ros-core"


def _why_not() -> str | None:
    if shutil.which("roscore") is None:
        return "needs Debian's ros-core for the edge master"
    return podman_missing(BASE, "the test base image")


pytestmark = [pytest.mark.ros, pytest.mark.skipif(_why_not() is not None, reason=_why_not() or "")]

DOCKERFILE = """FROM ros:noetic-ros-core
COPY talker.py /opt/talker.py
CMD ["python3", "/opt/talker.py"]
"""

TALKER = """import os
import rospy
from std_msgs.msg import String
rospy.init_node("built_talker")
pub = rospy.Publisher("/built", String, queue_size=1)
rate = rospy.Rate(5)
while not rospy.is_shutdown():
    pub.publish(String(data="built says " + os.environ["GREETING"]))
    rate.sleep()
"""

PACKAGE_XML = """<?xml version="1.0"?>
<package format="2">
  <name>fogcat</name><version>0.0.1</version><description>a catkin package built in the container</description>
  <maintainer email="test@example.com">test</maintainer><license>MIT</license>
  <buildtool_depend>catkin</buildtool_depend>
</package>
"""

CMAKE = """cmake_minimum_required(VERSION 3.0.2)
project(fogcat)
find_package(catkin REQUIRED)
catkin_package()
"""

CAT_TALKER = """#!/usr/bin/env python3
import pathlib
import rospy
import shellingham
from std_msgs.msg import String
rospy.init_node("cat_talker")
word = (pathlib.Path(__file__).parent / "word.txt").read_text().strip()
pub = rospy.Publisher("/cat", String, queue_size=1)
rate = rospy.Rate(5)
while not rospy.is_shutdown():
    pub.publish(String(data="cat says " + word + " on shellingham " + shellingham.__version__))
    rate.sleep()
"""

LAUNCH = """<launch>
  <node name="cat_talker" pkg="fogcat" type="talker.py" output="screen" required="true"/>
</launch>
"""


def _project(root: Path, *, name: str, edge_port: int) -> Path:
    app_dir = root / "app"
    app_dir.mkdir(parents=True)
    (app_dir / "Dockerfile").write_text(DOCKERFILE)
    (app_dir / "talker.py").write_text(TALKER)
    pkg = root / "ws" / "src" / "fogcat"
    (pkg / "scripts").mkdir(parents=True, exist_ok=True)
    (pkg / "launch").mkdir(exist_ok=True)
    (pkg / "package.xml").write_text(PACKAGE_XML)
    (pkg / "CMakeLists.txt").write_text(CMAKE)
    (pkg / "launch" / "talker.launch").write_text(LAUNCH)
    script = pkg / "scripts" / "talker.py"
    script.write_text(CAT_TALKER)
    script.chmod(0o755)
    (root / "ws" / "src" / "CMakeLists.txt").write_text(
        "cmake_minimum_required(VERSION 3.10)\nproject(Project)\ninclude(/usr/share/catkin/cmake/toplevel.cmake)\n")
    # Sourced inside the ROS image before catkin_make: what it writes, the node reads.
    (root / "setup.sh").write_text("echo meow > src/fogcat/scripts/word.txt\n")
    (root / "requirements.txt").write_text("# the package's own Python requirements\nshellingham==1.5.4\n")
    manifest = root / f"{name}.yaml"
    manifest.write_text(f"""name: {name}
cloud: {{provider: local, runtime: container}}
edge: {{ros_master: "http://127.0.0.1:{edge_port}"}}
nodes:
  - name: built
    machine: t3.small
    build: {{context: app}}
    env: {{GREETING: "hello from a private file"}}
    topics: {{out: [/built]}}
  - name: plain
    machine: t3.small
    image: ros:noetic-ros-core
    command: [rostopic, pub, -r, "5", /plain, std_msgs/String, "data: plain image"]
    topics: {{out: [/plain]}}
  - name: cat
    machine: t3.small
    launch: {{package: fogcat, file: talker.launch, workspace: ws, env_script: setup.sh,
              requirements: requirements.txt}}
    topics: {{out: [/cat]}}
""")
    return manifest


def _echo(edge_port: int, topic: str) -> str:
    env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{edge_port}", "ROS_HOSTNAME": "127.0.0.1"}
    done = subprocess.run(["rostopic", "echo", "-n", "1", topic], env=env, capture_output=True, text=True,
                          timeout=90)
    return done.stdout


def _containers(stack: str) -> list[str]:
    out = subprocess.run(["podman", "ps", "-a", "--filter", f"label=fogiac.stack={stack}", "--format",
                          "{{.Names}}"], capture_output=True, text=True, check=True).stdout
    return sorted(out.split())


def _listening(pids: set[int]) -> list[str]:
    """Local addresses of TCP listeners owned by ``pids``."""
    out = subprocess.run(["ss", "-Hltnp"], capture_output=True, text=True, check=True).stdout
    found = []
    for line in out.splitlines():
        owners = {int(p) for p in re.findall(r"pid=(\d+)", line)}
        if owners & pids:
            programs = re.findall(r'[(][(]"([^"]+)', line)
            found.append(f"{line.split()[3]} {' '.join(programs)}")
    return found


def _started_at(name: str) -> str:
    return subprocess.run(["podman", "inspect", "--format", "{{.State.StartedAt}}", name], capture_output=True,
                          text=True, check=True).stdout.strip()


def test_a_failed_build_is_one_line_naming_the_node_the_step_and_the_log(tmp_path: Path) -> None:
    context = tmp_path / "ctx"
    context.mkdir()
    (context / "Dockerfile").write_text("FROM ros:noetic-ros-core\nRUN echo first\nRUN exit 3\nRUN echo never\n")
    host = LocalHost(name="lab1", base=str(tmp_path / "base"))
    host.connect()
    recipe = images.Recipe(node="broken", repo="fogiac/test-broken", context=context, dockerfile="Dockerfile")
    log = f"{tmp_path}/base/build/broken.log"
    with pytest.raises(ProvisionError, match=r"^lab1: node broken: image build failed at STEP 3/4: RUN exit 3; "
                                             rf"log: {re.escape(log)}$"):
        images.build(host, recipe, engine="podman", base_id="x", dest=f"{tmp_path}/base/build/broken",
                     tmp_dir=f"{tmp_path}/base/tmp", log=log)


def _container_pids(stack: str) -> set[int]:
    pids: set[int] = set()
    for name in _containers(stack):
        top = subprocess.run(["podman", "top", name, "hpid"], capture_output=True, text=True).stdout
        pids |= {int(p) for p in top.split()[1:] if p.isdigit()}
    return pids


def test_build_and_launch_nodes_in_podman_two_stacks_and_down(tmp_path: Path, _state_dir: Path) -> None:
    runner = CliRunner()
    edge = free_port()
    first = _project(tmp_path / "one", name="ctra", edge_port=edge)
    second = _project(tmp_path / "two", name="ctrb", edge_port=edge)
    manifests = [first, second]
    try:
        up = runner.invoke(app, ["up", str(first), "--target", "local", "--yes", "--start-edge-master"])
        assert up.exit_code == 0, up.output
        assert "3 of 3 host(s) changed" in up.output
        assert _echo(edge, "/built").startswith('data: "built says hello from a private file"')
        assert _echo(edge, "/plain").startswith('data: "plain image"')
        assert _echo(edge, "/cat").startswith('data: "cat says meow on shellingham 1.5.4"')
        assert _containers("ctra-dev") == ["fogiac-ctra-dev-built", "fogiac-ctra-dev-built-ros-master",
                                           "fogiac-ctra-dev-cat", "fogiac-ctra-dev-cat-ros-master",
                                           "fogiac-ctra-dev-plain", "fogiac-ctra-dev-plain-ros-master"]
        sandbox = _state_dir / "ctra-dev" / "local"
        env_file = sandbox / "built" / "env" / "node-built.env"
        assert env_file.stat().st_mode & 0o777 == 0o600
        script = (sandbox / "built" / "services" / "node-built.sh").read_text()
        assert "hello from a private file" not in script and " --env-file " in script
        assert list((sandbox / "cat" / "ws").glob("*/devel/setup.bash")), "catkin_make did not run in the container"
        cat_image = subprocess.run(["podman", "inspect", "--format", "{{.ImageName}}", "fogiac-ctra-dev-cat"],
                                   capture_output=True, text=True, check=True).stdout.strip()
        assert re.fullmatch(r"localhost/fogiac/ctra-dev-cat:[0-9a-f]{16}", cat_image), "its requirements' image"

        # Every listener in fogiac's containers is on loopback, except the one roscpp's rosout
        # always binds to every interface (its TCPROS server; roscpp has no bind setting).
        listeners = _listening(_container_pids("ctra-dev"))
        assert listeners and all(a.startswith("127.0.0.1:") or "rosout" in a for a in listeners), listeners

        again = runner.invoke(app, ["up", str(first), "--target", "local", "--yes"])
        assert again.exit_code == 0 and "no changes" in again.output, again.output

        # One file of one node changed: that node's image is rebuilt and restarted, the other left alone.
        started = _started_at("fogiac-ctra-dev-cat")
        talker = tmp_path / "one" / "app" / "talker.py"
        talker.write_text(talker.read_text().replace('"built says "', '"rebuilt says "'))
        changed = runner.invoke(app, ["up", str(first), "--target", "local", "--yes"])
        assert changed.exit_code == 0 and "1 of 3 host(s) changed" in changed.output, changed.output
        assert _echo(edge, "/built").startswith('data: "rebuilt says hello from a private file"')
        assert _started_at("fogiac-ctra-dev-cat") == started

        # A second stack with the same node names on the same machine: both healthy.
        up2 = runner.invoke(app, ["up", str(second), "--target", "local", "--yes"])
        assert up2.exit_code == 0, up2.output
        assert "built 0" not in up2.output
        down2 = runner.invoke(app, ["down", str(second), "--target", "local", "--yes"])
        assert down2.exit_code == 0 and "nothing left" in down2.output, down2.output
        assert _containers("ctrb-dev") == []
        assert len(_containers("ctra-dev")) == 6
        assert _echo(edge, "/cat").startswith('data: "cat says meow on shellingham 1.5.4"')
    finally:
        for manifest in manifests:
            runner.invoke(app, ["down", str(manifest), "--target", "local", "--yes"])
    assert _containers("ctra-dev") == [] and _containers("ctrb-dev") == []


def test_motion_planning_workload_built_from_its_recipe_answers_through_the_relay(
        tmp_path: Path, _state_dir: Path) -> None:
    runner = CliRunner()
    edge = free_port()
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text((EXAMPLES / "motion-planning.yaml").read_text()
                        .replace("ros_master: http://localhost:11311", f"ros_master: http://127.0.0.1:{edge}")
                        .replace("  provider: aws\n", "  provider: aws\n  runtime: container\n"))
    try:
        up = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes", "--start-edge-master"])
        assert up.exit_code == 0, up.output
        (name,) = [n for n in _containers("motion-planning-dev") if not n.endswith("-ros-master")]
        image = subprocess.run(["podman", "inspect", "--format", "{{.ImageName}}", name], capture_output=True,
                               text=True, check=True).stdout.strip()
        assert re.fullmatch(r"localhost/fogiac/motion_planning:[0-9a-f]{16}", image), image
        answer = ask_planner(edge, cwd=tmp_path)
        assert answer["solved"] and answer["poses"] >= 2 and answer["free"], answer
        again = runner.invoke(app, ["up", str(manifest), "--target", "local", "--yes"])
        assert again.exit_code == 0 and "no changes" in again.output, again.output
    finally:
        down = runner.invoke(app, ["down", str(manifest), "--target", "local", "--yes"])
    assert down.exit_code == 0 and "nothing left" in down.output, down.output
    assert _containers("motion-planning-dev") == []
