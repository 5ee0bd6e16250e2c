"""load_manifest: typed models from YAML, and one actionable line per problem."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from fogiac.errors import ManifestError
from fogiac.manifest.schema import Manifest, json_schema, load_manifest, parse_manifest

from .conftest import EXAMPLES

VALID = """\
name: demo
cloud:
  provider: aws
  region: us-west-2
nodes:
  - name: planner
    machine: c5.24xlarge
    workload: motion_planning
  - name: grasp
    machine: g4dn.xlarge
    gpu: true
    image: example/grasp:1
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "fogiac.yaml"
    path.write_text(textwrap.dedent(text))
    return path


def problems(tmp_path: Path, text: str) -> list[str]:
    path = write(tmp_path, text)
    with pytest.raises(ManifestError) as info:
        load_manifest(path)
    prefix = f"{path}:"
    assert all(line.startswith(prefix) for line in info.value.problems), info.value.problems
    return [line[len(prefix):] for line in info.value.problems]


def test_valid_manifest_loads_frozen_with_defaults(tmp_path: Path) -> None:
    manifest = load_manifest(write(tmp_path, VALID))
    assert isinstance(manifest, Manifest)
    assert [n.name for n in manifest.nodes] == ["planner", "grasp"]
    assert manifest.ros.distro == "noetic"
    assert str(manifest.network.vpc_cidr) == "10.10.0.0/16"
    assert manifest.network.ssh_from == "auto"
    assert manifest.nodes[0].kind == "workload" and manifest.nodes[1].kind == "image"
    with pytest.raises(Exception, match="frozen"):
        manifest.name = "other"  # type: ignore[misc]


@pytest.mark.parametrize("path", sorted(EXAMPLES.glob("*.yaml")), ids=lambda p: p.name)
def test_every_example_validates(path: Path) -> None:
    assert load_manifest(path).nodes


def test_unknown_instance_type_suggests_the_nearest(tmp_path: Path) -> None:
    text = VALID.replace("g4dn.xlarge", "g4dn.xlrge")
    assert problems(tmp_path, text) == [
        "10: nodes[1].machine: 'g4dn.xlrge' is not a known instance type; did you mean 'g4dn.xlarge'?"
    ]


def test_all_problems_are_reported_at_once_in_file_order(tmp_path: Path) -> None:
    text = """\
    name: Bad_Name
    cloud:
      provider: awss
    network:
      ssh_fromm: auto
    nodes:
      - name: a
        machine: c5.large
        imag: x
    """
    assert problems(tmp_path, text) == [
        "1: name: 'Bad_Name' is not DNS-safe (lowercase letters, digits, '-', up to 40)",
        "3: cloud.provider: 'awss' is not one of 'aws', 'hosts', 'local'; did you mean 'aws'?",
        "5: network.ssh_fromm: unknown key; did you mean 'ssh_from'?",
        "9: nodes[0].imag: unknown key; did you mean 'image'?",
    ]


def test_yaml_syntax_error_is_one_line_with_its_line(tmp_path: Path) -> None:
    assert problems(tmp_path, "name: demo\nnodes: [\n  - a: b\n") == [
        "3: invalid YAML: expected the node content, but found '-'"
    ]


def test_duplicate_keys_are_an_error_not_silently_the_last(tmp_path: Path) -> None:
    assert problems(tmp_path, VALID + "name: again\n") == ["13: name: key given twice"]


def test_client_cidr_rules(tmp_path: Path) -> None:
    overlap = VALID.replace("nodes:", "network:\n  vpc_cidr: 10.0.0.0/16\n  client_cidr: 10.0.0.0/22\nnodes:")
    assert problems(tmp_path, overlap) == ["7: network.client_cidr: 10.0.0.0/22 overlaps vpc_cidr 10.0.0.0/16"]
    too_small = VALID.replace("nodes:", "network:\n  client_cidr: 10.200.0.0/24\nnodes:")
    assert problems(tmp_path, too_small) == [
        "6: network.client_cidr: 10.200.0.0/24 must be between /12 and /22 (AWS Client VPN's limits)"
    ]


def test_vpc_must_hold_two_subnets_of_at_least_slash_27(tmp_path: Path) -> None:
    text = VALID.replace("nodes:", "network:\n  vpc_cidr: 10.0.0.0/27\nnodes:")
    assert problems(tmp_path, text) == [
        "6: network.vpc_cidr: 10.0.0.0/27 must be between /16 and /26 (it holds two subnets of at least /27)"
    ]


def test_ssh_from_the_whole_internet_is_refused(tmp_path: Path) -> None:
    text = VALID.replace("nodes:", "network:\n  ssh_from: [0.0.0.0/0]\nnodes:")
    assert problems(tmp_path, text) == [
        "6: network.ssh_from: 0.0.0.0/0 opens SSH to the whole internet; name your own network"
    ]


def test_unique_node_names(tmp_path: Path) -> None:
    text = VALID.replace("name: grasp", "name: planner")
    assert problems(tmp_path, text) == ["9: nodes[1].name: duplicate node name 'planner'"]


def test_exactly_one_of_image_launch_workload(tmp_path: Path) -> None:
    both = VALID.replace("    workload: motion_planning\n", "    workload: motion_planning\n    image: x\n")
    assert problems(tmp_path, both) == [
        "6: nodes[0]: needs exactly one of image, build, launch, workload or command (got image and workload)"
    ]
    none = VALID.replace("    workload: motion_planning\n", "")
    assert problems(tmp_path, none) == [
        "6: nodes[0]: needs exactly one of image, build, launch, workload or command (got none)"
    ]


def test_gpu_node_on_a_machine_without_one(tmp_path: Path) -> None:
    text = VALID.replace("g4dn.xlarge", "c5.xlarge")
    assert problems(tmp_path, text) == [
        "10: nodes[1].machine: 'c5.xlarge' has no GPU but the node sets gpu: true; pick a GPU type such as 'g4dn.xlarge'"
    ]


def test_zone_must_belong_to_the_region(tmp_path: Path) -> None:
    text = VALID.replace("region: us-west-2", "region: us-west-2\n  zone: us-east-1a")
    assert problems(tmp_path, text) == ["5: cloud.zone: 'us-east-1a' is not a zone of us-west-2"]


def test_unsupported_region_lists_the_supported_ones(tmp_path: Path) -> None:
    text = VALID.replace("us-west-2", "us-west-9")  # us-west-1 and -2 are one edit away: the name breaks the tie
    assert problems(tmp_path, text) == [
        "4: cloud.region: 'us-west-9' is not a supported region; did you mean 'us-west-1'?"
    ]


def test_launch_paths_are_resolved_and_checked(tmp_path: Path) -> None:
    (tmp_path / "ws").mkdir()
    text = VALID.replace(
        "    workload: motion_planning\n",
        "    launch: {package: demo, file: demo.launch, workspace: ws, env_script: setup.sh}\n",
    )
    assert problems(tmp_path, text) == [
        f"8: nodes[0].launch.env_script: 'setup.sh' does not exist (looked for {tmp_path / 'setup.sh'})"
    ]
    (tmp_path / "setup.sh").write_text("true\n")
    manifest = load_manifest(tmp_path / "fogiac.yaml")
    assert manifest.nodes[0].launch is not None
    assert manifest.nodes[0].launch.workspace == tmp_path / "ws"


def test_topics_must_be_absolute_ros_names(tmp_path: Path) -> None:
    text = VALID.replace("    workload: motion_planning\n", "    workload: motion_planning\n    topics: {in: [camera]}\n")
    assert problems(tmp_path, text) == [
        "9: nodes[0].topics.in: 'camera' is not a ROS topic name (absolute, like '/camera/depth')"
    ]


def test_hosts_node_must_name_a_listed_host(tmp_path: Path) -> None:
    (tmp_path / "id").write_text("key")
    text = VALID.replace(
        "  region: us-west-2\n",
        "  region: us-west-2\n  hosts:\n    - {name: lab, address: 10.0.0.5, key: id}\n",
    ).replace("    gpu: true\n", "    gpu: true\n    host: labb\n")
    assert problems(tmp_path, text) == ["14: nodes[1].host: 'labb' is not in cloud.hosts; did you mean 'lab'?"]


def test_reserved_tag_prefix(tmp_path: Path) -> None:
    assert problems(tmp_path, VALID + "tags: {'fogiac:stack': x}\n") == [
        "13: tags: tag 'fogiac:stack' uses a reserved prefix (fogiac:, aws:)"
    ]


def test_top_level_must_be_a_mapping(tmp_path: Path) -> None:
    assert problems(tmp_path, "- a\n- b\n") == ["1: the manifest must be a mapping (name:, nodes:, ...)"]


def test_missing_file_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(ManifestError, match=r"^.*nope\.yaml: no such file$"):
        load_manifest(tmp_path / "nope.yaml")


def test_parse_without_a_file_names_the_source() -> None:
    with pytest.raises(ManifestError, match=r"^<manifest>:1: nodes: required key is missing$"):
        parse_manifest("name: x\n")


def test_json_schema_describes_the_manifest() -> None:
    schema = json_schema()
    assert schema["title"] == "fogiac manifest"
    assert set(schema["required"]) == {"name", "nodes"}
    node = schema["$defs"]["Node"]
    assert node["additionalProperties"] is False
    assert "machine" in node["properties"]
    assert "in" in schema["$defs"]["TopicLists"]["properties"]


def test_an_image_reference_is_checked_by_its_grammar(tmp_path: Path) -> None:
    for good in ("ros:noetic-ros-core", "ghcr.io/org/app:1.0", "localhost:5000/a/b_c", "a@sha256:" + "0" * 64):
        assert load_manifest(write(tmp_path, VALID.replace("example/grasp:1", good))).nodes[1].image == good
    # An image starting with "-" would be read by the engine as an option.
    assert problems(tmp_path, VALID.replace("example/grasp:1", "'--privileged'")) == [
        "12: nodes[1].image: '--privileged' is not an image reference like 'ros:noetic-ros-core' "
        "or 'ghcr.io/org/app:1.0'"
    ]


def test_a_build_node_names_a_context_folder_and_a_dockerfile_in_it(tmp_path: Path) -> None:
    (tmp_path / "app").mkdir()
    text = VALID.replace("    image: example/grasp:1\n", "    build: {context: app}\n")
    assert problems(tmp_path, text) == [
        f"12: nodes[1].build.dockerfile: 'Dockerfile' is not a file in {tmp_path / 'app'}"
    ]
    (tmp_path / "app" / "Dockerfile").write_text("FROM ros:noetic-ros-core\n")
    node = load_manifest(write(tmp_path, text)).nodes[1]
    assert node.kind == "image" and node.build is not None and node.build.context == tmp_path / "app"
    outside = text.replace("{context: app}", "{context: app, dockerfile: ../Dockerfile}")
    assert problems(tmp_path, outside) == [
        "12: nodes[1].build.dockerfile: '../Dockerfile' must be a path inside the context folder"
    ]


def test_runtime_is_a_choice(tmp_path: Path) -> None:
    text = VALID.replace("  region: us-west-2\n", "  region: us-west-2\n  runtime: docker\n")
    (line,) = problems(tmp_path, text)
    assert line.startswith("5: cloud.runtime: ") and "'auto', 'container', 'native'" in line
