"""FogROS2 launch files (Python) become fogiac manifests: read with ast, never imported or run."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.errors import ManifestError
from fogiac.manifest.fogros import load_any
from fogiac.manifest.fogros2 import docker_node, import_launch
from fogiac.manifest.schema import load_manifest

# Shaped like FogROS2's own examples (talker on AWS, a docker container on the machine), written here.
LAUNCH = '''\
"""Perception in the cloud."""
from launch_ros.actions import Node

import fogros2
from fogros2 import AWS, CloudNode, FogROSLaunchDescription


def pick_ami():
    import lsb_release  # only on the robot; fogiac chooses its own images
    return {"22.04": "ami-0123"}[lsb_release.get_os_release()["RELEASE"]]


SERVER = ("sudo docker run --net=host --gpus all --env RMW_IMPLEMENTATION=rmw_cyclonedds_cpp "
          "--env MODEL=/models/dexnet -v /home/ubuntu/cyclonedds.xml:/tmp/cyclonedds.xml --rm -it "
          "ghcr.io/lab/grasp:humble ros2 launch grasp planner.launch.py")


def generate_launch_description():
    """Detector and grasp planner in the cloud, camera on the robot."""
    ld = FogROSLaunchDescription()
    machine = AWS(region="us-west-2", ec2_instance_type="g4dn.xlarge", ami_image=pick_ami(), disk_size=60)
    machine.add_docker_container(SERVER)
    camera = Node(package="usb_cam", executable="usb_cam_node_exe", output="screen")
    detector = CloudNode(package="perception", executable="detector", output="screen", machine=machine)
    ld.add_action(camera)
    ld.add_action(detector)
    ld.add_action(fogros2.CloudNode(package="perception", executable="tracker", name="track", machine=machine))
    return ld
'''


def write(tmp_path: Path, text: str, name: str = "perception.launch.py") -> Path:
    path = tmp_path / "src" / "bringup" / "launch" / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def test_cloud_nodes_and_containers_become_nodes_on_their_machine(tmp_path: Path) -> None:
    manifest, text, _ = import_launch(write(tmp_path, LAUNCH))
    assert (manifest.name, manifest.ros.distro, manifest.cloud.provider, manifest.cloud.region) == (
        "perception", "humble", "aws", "us-west-2")
    assert [(n.name, n.machine, n.image, n.command) for n in manifest.nodes] == [
        ("detector", "g4dn.xlarge", "ros:humble-ros-base", ("ros2", "run", "perception", "detector")),
        ("track", "g4dn.xlarge", "ros:humble-ros-base", ("ros2", "run", "perception", "tracker")),
        ("grasp", "g4dn.xlarge", "ghcr.io/lab/grasp:humble", ("ros2", "launch", "grasp", "planner.launch.py")),
    ]
    grasp = manifest.nodes[2]
    assert grasp.env == {"MODEL": "/models/dexnet"}  # the DDS choice is dropped: fogiac's Zenoh carries topics
    assert grasp.gpu and grasp.disk_gb == 60
    assert all(n.topics != "auto" and not n.topics.inputs and not n.topics.outputs for n in manifest.nodes)
    assert "#   - usb_cam/usb_cam_node_exe" in text
    assert "build an image FROM ros:humble-ros-base holding package perception" in text
    assert "grasp: the container's volumes (-v) name paths on FogROS2's machine" in text


def test_the_file_is_never_imported_or_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    marker = tmp_path / "ran"
    # A helper that writes the marker feeds AWS's ami_image, and a module it imports would too.
    (tmp_path / "evil_helper.py").write_text(f"open({str(marker)!r}, 'w').write('imported')\n")
    side_effects = LAUNCH.replace(
        "def pick_ami():\n", f"def pick_ami():\n    open({str(marker)!r}, 'w').write('called')\n"
    ).replace("import fogros2\n", "import evil_helper\nimport fogros2\n")
    monkeypatch.syspath_prepend(str(tmp_path))  # were the file imported, evil_helper would be found and run
    path = write(tmp_path, side_effects)
    assert [n.name for n in load_any(path).nodes] == ["detector", "track", "grasp"]
    assert not marker.exists()
    # A statement that would act at import time is not a FogROS2 construct: one line, still not run.
    path.write_text(side_effects + f"\nopen({str(marker)!r}, 'w').write('module')\n")
    with pytest.raises(ManifestError) as info:
        import_launch(path)
    line = len(side_effects.splitlines()) + 2
    assert len(info.value.problems) == 1
    assert info.value.problems[0].startswith(f"{path}:{line}: fogiac cannot import \"open(")
    assert not marker.exists()


def test_unknown_constructs_give_one_line_each_naming_file_and_line(tmp_path: Path) -> None:
    text = LAUNCH.replace(
        'output="screen", machine=machine)', "machine=fogros2.GCP(zone='us-central1-a'))"
    ).replace("    ld.add_action(camera)\n", "    for extra in range(2):\n        ld.add_action(camera)\n").replace(
        'ec2_instance_type="g4dn.xlarge"', 'ec2_instance_type="t2.mirco"')
    path = write(tmp_path, text)
    with pytest.raises(ManifestError) as info:
        import_launch(path)
    lines = text.splitlines()
    at = {key: next(i + 1 for i, line in enumerate(lines) if key in line) for key in ("t2.mirco", "for extra", "GCP")}
    assert info.value.problems == [
        f"{path}:{at['t2.mirco']}: ec2_instance_type: 't2.mirco' is not a known instance type; did you mean "
        "'t2.micro'?",
        f"{path}:{at['GCP']}: FogROS2's GCP machines are not imported: fogiac runs on AWS (AWSCloudInstance, "
        "target aws) or on machines you have (target hosts)",
        f"{path}:{at['for extra']}: fogiac cannot import 'for extra in range(2):' (not a FogROS2 construct it knows)",
    ]


def test_not_python_and_not_a_launch_file_name_the_line(tmp_path: Path) -> None:
    with pytest.raises(ManifestError, match=r"broken\.launch\.py:2: not valid Python: "):
        import_launch(write(tmp_path, "x = 1\ndef (:\n", "broken.launch.py"))
    with pytest.raises(ManifestError, match=r"plain\.py:1: no generate_launch_description\(\) here"):
        import_launch(write(tmp_path, "x = 1\n", "plain.py"))


def test_docker_run_words() -> None:
    assert docker_node("docker run -e A=1 --env=B=2 --name x -it img:1 python -m app") == (
        "img:1", ("python", "-m", "app"), {"A": "1", "B": "2"}, False)
    assert docker_node("podman run img") is None


def test_cli_imports_by_file_kind_and_refuses_others(tmp_path: Path) -> None:
    launch = write(tmp_path, LAUNCH)
    out = tmp_path / "fogiac.yaml"
    result = CliRunner().invoke(app, ["import", str(launch), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert [n.name for n in load_manifest(out).nodes] == ["detector", "track", "grasp"]
    assert yaml.safe_load(out.read_text())["nodes"][0]["topics"] == {"in": [], "out": []}
    other = tmp_path / "notes.txt"
    other.write_text("hi\n")
    result = CliRunner().invoke(app, ["import", str(other), "--out", str(tmp_path / "x.yaml")])
    assert result.exit_code == 1
    assert result.output.strip() == (
        f"{other}: not a launch file fogiac imports; it reads: FogROS roslaunch XML (.launch, .xml); "
        "FogROS2 Python launch file (.py)")
    assert not (tmp_path / "x.yaml").exists()


# FogROS2's own talker.aws.launch.py, as its repository ships it (the AMI helper runs only on the robot).
TALKER = '''\
from launch_ros.actions import Node

import fogros2


def ami_image():
    import lsb_release

    ubuntu_release = lsb_release.get_os_release()["RELEASE"]
    if ubuntu_release == "20.04":
        return "ami-00f25057ddc9b310b"
    if ubuntu_release == "22.04":
        return "ami-0b6030c78f8b2f076"
    raise ValueError(f"No AMI for {ubuntu_release}")


def generate_launch_description():
    """Talker example that launches the listener locally and the talker in the cloud."""
    ld = fogros2.FogROSLaunchDescription()
    machine1 = fogros2.AWSCloudInstance(
        region="us-west-1", ec2_instance_type="t2.micro", ami_image=ami_image()
    )

    listener_node = Node(
        package="fogros2_examples", executable="listener", output="screen"
    )

    talker_node = fogros2.CloudNode(
        package="fogros2_examples",
        executable="talker",
        output="screen",
        machine=machine1,
    )
    ld.add_action(talker_node)
    ld.add_action(listener_node)
    return ld
'''


def test_fogros2s_talker_imports_and_plans(tmp_path: Path) -> None:
    from fogiac.plan.compile import compile_plan

    converted = import_launch(write(tmp_path, TALKER, "talker.aws.launch.py"))
    assert (converted.manifest.cloud.region, [n.machine for n in converted.manifest.nodes]) == ("us-west-1",
                                                                                               ["t2.micro"])
    assert "#   - fogros2_examples/listener" in converted.text
    assert "#   - ami_image dropped: fogiac picks each machine's image by its architecture" in converted.text
    plan = compile_plan(converted.manifest, target="aws")
    assert (plan.host("talker").machine, plan.host("talker").usd_per_hour) == ("t2.micro", 0.01382)
    from fogiac.targets.aws.manifest import CLOUD

    assert CLOUD.price_note("t2.micro", "us-west-1") == (
        "t2.micro in us-west-1: $0.01382/h on-demand (estimate), estimate: us-east-1 price x the region's median "
        "price ratio (2026-07-20)")


# The way FogROS2's documentation and users write it today: AWSCloudInstance, the region helper, the
# cheapest-type helper, a GPU machine in sa-east-1 (a region the catalogue cannot price) and a loop.
CURRENT = '''\
import fogros2
from launch_ros.actions import Node

REGIONS = {"eu-west-1": {"ami_image": "ami-0eu"}, "us-west-1": {"ami_image": "ami-0us"}}


def generate_launch_description():
    ld = fogros2.FogROSLaunchDescription()
    region, ami = fogros2.find_nearest_region_and_ami(REGIONS)
    arm = fogros2.AWSCloudInstance(region=region, ec2_instance_type="t2.xlarge", ami_image=ami)
    cheap = fogros2.AWSCloudInstance(region=region, ami_image=ami,
                                     ec2_instance_type=fogros2.find_cheapest_ec2_instance_type(region, "x86_64", 2))
    talker = fogros2.CloudNode(package="demo", executable="talker", machine=arm)
    listener = fogros2.CloudNode(package="demo", executable="listener", machine=cheap)
    for a in (talker, listener):
        ld.add_action(a)
    return ld
'''


def test_the_current_style_imports_with_the_helpers_as_fogiac_choices(tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    from fogiac.plan.compile import compile_plan

    monkeypatch.setenv("TZ", "UTC")  # the region is the listed one nearest this machine's time zone; UTC places none

    converted = import_launch(write(tmp_path, CURRENT, "current.launch.py"))
    manifest = converted.manifest
    assert manifest.cloud.region == "eu-west-1"
    assert ("#   - cloud.region: FogROS2 picked the region nearest the robot at launch time among eu-west-1, "
            "us-west-1 (find_nearest_region_and_ami); fogiac uses the first, eu-west-1: set yours") in converted.text
    plan = compile_plan(manifest, target="aws")
    assert plan.host("talker").machine == "t2.xlarge"
    listener = plan.host("listener")
    assert (listener.chosen_for, listener.vcpus) == ("vcpus == 2", 2)  # the requirement, resolved offline

    gpu = CURRENT.replace("region=region, ec2_instance_type=\"t2.xlarge\"",
                          "region=\"sa-east-1\", ec2_instance_type=\"g4dn.xlarge\"").replace(
        "region=region, ami_image=ami,\n", "region=\"sa-east-1\",\n").replace(
        "fogros2.find_cheapest_ec2_instance_type(region, \"x86_64\", 2)", "\"t3.small\"")
    with pytest.warns(UserWarning, match=r"g4dn\.xlarge in sa-east-1: cost unknown"):
        converted = import_launch(write(tmp_path, gpu, "gpu.launch.py"))
    assert converted.manifest.cloud.region == "sa-east-1"


def test_other_fogros2_clouds_are_refused_in_one_line(tmp_path: Path) -> None:
    text = TALKER.replace('fogros2.AWSCloudInstance(\n        region="us-west-1", ec2_instance_type="t2.micro", '
                          'ami_image=ami_image()\n    )', 'fogros2.GCPCloudInstance(project_id="lab")')
    path = write(tmp_path, text, "gcp.launch.py")
    with pytest.raises(ManifestError) as info:
        import_launch(path)
    line = next(i + 1 for i, t in enumerate(text.splitlines()) if "GCPCloudInstance" in t)
    assert info.value.problems == [
        f"{path}:{line}: FogROS2's GCP machines are not imported: fogiac runs on AWS (AWSCloudInstance, target aws) "
        "or on machines you have (target hosts)"]


def test_an_imported_manifest_with_empty_topic_lists_validates_with_a_warning(tmp_path: Path) -> None:
    """Issue 35 item 24: the empty lists an import writes validated without a word; each such node is said."""
    out = tmp_path / "fogiac.yaml"
    result = CliRunner().invoke(app, ["import", str(write(tmp_path, TALKER, "talker.aws.launch.py")), "-o", str(out)])
    assert result.exit_code == 0, result.output
    result = CliRunner().invoke(app, ["validate", str(out)])
    assert result.exit_code == 0, result.output
    assert result.output.splitlines() == [
        f"{out}: valid (1 node, 1 host, target aws)",
        "warning: node talker: topics in and out are both empty, so nothing crosses between it and the robot; list "
        "the topics it reads from the robot (in) and sends back (out)"]
    out.write_text(out.read_text().replace("    out: []", "    out: [/chatter]"))
    result = CliRunner().invoke(app, ["validate", str(out)])
    assert (result.exit_code, result.output.strip()) == (0, f"{out}: valid (1 node, 1 host, target aws)")
