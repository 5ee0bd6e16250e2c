"""FogROS launch files become fogiac manifests; bad ones give error lines and write nothing."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.errors import ManifestError
from fogiac.manifest.fogros import import_launch, load_any
from fogiac.manifest.schema import load_manifest

ROBOT_LAUNCH = """\
<launch>
  <node pkg="turtlebot_teleop" type="keyboard" name="teleop"/>
  <node pkg="fogros" type="fogros_launch.py" name="cloud_planner" output="screen">
    <rosparam>
      instance_type: c5.4xlarge
      launch_file: $(find planner)/launch/planner.launch
      env_script: ../../../setup_env.sh
    </rosparam>
  </node>
  <node pkg="fogros" type="fogros_docker.py" name="dexnet">
    <rosparam>
      docker_image: keplerc/dexnet:latest
      machine_type: g4dn.xlarge
    </rosparam>
  </node>
</launch>
"""


def make_workspace(root: Path, launch_text: str = ROBOT_LAUNCH) -> Path:
    planner = root / "ws" / "src" / "planner"
    (planner / "launch").mkdir(parents=True)
    (planner / "package.xml").write_text("<package><name>planner</name></package>\n")
    (planner / "launch" / "planner.launch").write_text("<launch/>\n")
    bringup = root / "ws" / "src" / "bringup"
    (bringup / "launch").mkdir(parents=True)
    (bringup / "package.xml").write_text("<package><name>bringup</name></package>\n")
    (root / "ws" / "setup_env.sh").write_text("true\n")
    robot = bringup / "launch" / "robot.launch"
    robot.write_text(launch_text)
    return robot


def test_both_kinds_of_fogros_node_import(tmp_path: Path) -> None:
    robot = make_workspace(tmp_path)
    manifest, text, _ = import_launch(robot)
    assert [(n.name, n.machine, n.kind) for n in manifest.nodes] == [
        ("cloud-planner", "c5.4xlarge", "launch"),
        ("dexnet", "g4dn.xlarge", "image"),
    ]
    launch = manifest.nodes[0].launch
    assert launch is not None
    assert (launch.package, launch.file) == ("planner", "planner.launch")
    assert launch.workspace == tmp_path / "ws"
    assert launch.env_script == tmp_path / "ws" / "setup_env.sh"
    assert manifest.nodes[1].image == "keplerc/dexnet:latest"
    assert "#   - teleop (turtlebot_teleop/keyboard)" in text


def test_cli_writes_a_manifest_that_validates_elsewhere(tmp_path: Path) -> None:
    robot = make_workspace(tmp_path)
    out = tmp_path / "deploy" / "fogiac.yaml"
    result = CliRunner().invoke(app, ["import", str(robot), "--out", str(out)])
    assert result.exit_code == 0, result.output
    manifest = load_manifest(out)
    assert manifest.nodes[0].launch is not None and manifest.nodes[0].launch.workspace == tmp_path / "ws"
    assert yaml.safe_load(out.read_text())["nodes"][0]["launch"]["workspace"] == "../ws"
    again = CliRunner().invoke(app, ["import", str(robot), "--out", str(out)])
    assert again.exit_code == 1 and again.output.strip() == f"error: {out} exists; pass --force to overwrite it"


def test_load_any_reads_launch_files_directly(tmp_path: Path) -> None:
    robot = make_workspace(tmp_path)
    assert [n.name for n in load_any(robot).nodes] == ["cloud-planner", "dexnet"]


def test_missing_params_and_bad_type_are_reported_with_lines(tmp_path: Path) -> None:
    text = """\
<launch>
  <node pkg="fogros" type="fogros_launch.py" name="a">
    <rosparam>instance_type: c5.large</rosparam>
  </node>
  <node pkg="fogros" type="fogros_ssh.py" name="b"/>
</launch>
"""
    robot = make_workspace(tmp_path, text)
    with pytest.raises(ManifestError) as info:
        import_launch(robot)
    assert info.value.problems == [
        f"{robot}:2: node 'a': fogros_launch.py needs rosparam 'launch_file'",
        f"{robot}:5: node 'b': unknown FogROS node type 'fogros_ssh.py'; valid: 'fogros_launch.py', 'fogros_docker.py'",
    ]


def test_bad_machine_is_a_manifest_error_and_nothing_is_written(tmp_path: Path) -> None:
    robot = make_workspace(tmp_path, ROBOT_LAUNCH.replace("g4dn.xlarge", "g4dn.xlrge"))
    out = tmp_path / "fogiac.yaml"
    result = CliRunner().invoke(app, ["import", str(robot), "--out", str(out)])
    assert result.exit_code == 1
    assert "nodes[1].machine: 'g4dn.xlrge' is not a known instance type; did you mean 'g4dn.xlarge'?" in result.output
    assert not out.exists()


def test_invalid_xml_names_the_line(tmp_path: Path) -> None:
    robot = make_workspace(tmp_path, "<launch>\n  <node pkg='x'\n</launch>\n")
    with pytest.raises(ManifestError, match=r"robot\.launch:3: invalid XML: not well-formed \(invalid token\)$"):
        import_launch(robot)
