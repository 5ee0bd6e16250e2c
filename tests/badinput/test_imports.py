"""Hostile launch files given to ``fogiac import`` and to ``plan``/``validate`` directly (issue 35 items 1, 13).

A robot-local node's package holding a newline (FogROS2, Python) or ``&#10;`` in a ``<node name>``
(FogROS, XML) went raw into the written manifest's header, so the line broke and what followed became
top-level keys: ``network: {ssh_from: [10.0.0.0/8]}`` validated and opened SSH and the ROS ports to it,
and ``plan``/``up`` on the launch file read the same keys. An escape character gave "invalid YAML"
naming the ``--out`` file, never written. Here every string a launch file feeds the manifest carries
each line break YAML or Python knows (and an escape, a form feed), in every place it can stand: the
import either writes a manifest with exactly the keys fogiac put there and one comment line per header
line, or refuses in lines naming the launch file and writes nothing.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.errors import ManifestError
from fogiac.manifest.fogros_yaml import FromLaunch, dump
from fogiac.manifest.importers import load_any

BREAKS = {"lf": "\n", "cr": "\r", "crlf": "\r\n", "nel": "\x85", "ls": "\u2028", "ps": "\u2029", "vt": "\x0b",
          "ff": "\x0c", "esc": "\x1b"}
KEYS = {"name", "ros", "cloud", "nodes", "allow_paths_outside"}  # all an import writes at the top


def _payload(brk: str) -> str:
    return f"x{brk}network:{brk}  ssh_from: [10.0.0.0/8]{brk}tags: {{a: b}}{brk}#"


def _py(where: str, payload: str) -> str:
    """A FogROS2 launch file with ``payload`` (a Python string literal's text) in one place."""
    lit = repr(payload)
    fields = {"local": lit if where == "local" else "'cam'", "package": lit if where == "package" else "'demo'",
              "executable": lit if where == "executable" else "'talker'",
              "image": f"'docker run -e K={payload!r} img ' + {lit}" if where == "image" else "'docker run img:1'",
              "region": "{" + lit + ": {}, 'us-west-1': {}}" if where == "region" else "{'us-west-1': {}}"}
    return f'''\
import fogros2
from launch_ros.actions import Node


def generate_launch_description():
    ld = fogros2.FogROSLaunchDescription()
    region, ami = fogros2.find_nearest_region_and_ami({fields["region"]})
    machine = fogros2.AWSCloudInstance(region=region, ec2_instance_type="t3.small", ami_image=ami)
    machine.add_docker_container({fields["image"]})
    ld.add_action(Node(package={fields["local"]}, executable="cam_node"))
    ld.add_action(fogros2.CloudNode(package={fields["package"]}, executable={fields["executable"]}, machine=machine))
    return ld
'''


def _xml_escape(text: str) -> str:
    return "".join(f"&#{ord(c)};" if not c.isprintable() else c for c in text).replace('"', "&quot;")


def _xml(where: str, payload: str) -> str | None:
    """A FogROS launch file with ``payload`` in one attribute or rosparam; None where XML cannot carry it."""
    if any(ord(c) < 0x20 and c not in "\n\r\t" for c in payload):
        return None  # XML 1.0 has no way to write an escape or a form feed, even as a reference
    value = _xml_escape(payload)
    attr = {k: value if where == k else d for k, d in (("name", "teleop"), ("pkg", "turtlebot"), ("type", "key"))}
    image = f'"{value}"' if where == "docker_image" else "keplerc/dexnet:latest"
    machine = f'"{value}"' if where == "machine_type" else "g4dn.xlarge"
    return f'''\
<launch>
  <node pkg="{attr["pkg"]}" type="{attr["type"]}" name="{attr["name"]}"/>
  <node pkg="fogros" type="fogros_docker.py" name="dexnet">
    <rosparam>
      docker_image: {image}
      machine_type: {machine}
    </rosparam>
  </node>
</launch>
'''


def _cases() -> list[tuple[str, str, str]]:
    cases = [(f"py-{where}-{b}", "robot.launch.py", _py(where, _payload(brk)))
             for where in ("local", "package", "executable", "image", "region") for b, brk in BREAKS.items()]
    for where in ("name", "pkg", "type", "docker_image", "machine_type"):
        for b, brk in BREAKS.items():
            text = _xml(where, _payload(brk))
            if text is not None:
                cases.append((f"xml-{where}-{b}", "robot.launch", text))
    cases += [(f"filename-{b}", f"evil{_payload(brk).replace('/', '-')}.launch.py", _py("none", ""))
              for b, brk in BREAKS.items()]  # a file name holds no "/"
    return cases


CASES = {case: (name, text) for case, name, text in _cases()}


def _check_written(text: str, launch: Path) -> None:
    """The manifest's header is comment lines, one each, and its keys are fogiac's; nothing unprintable."""
    assert all(c.isprintable() or c == "\n" for c in text), repr(text)
    header = text.split("\nname: ", 1)[0].split("\n")
    assert all(line.startswith("#") for line in header), header
    data = yaml.safe_load(text)
    assert set(data) <= KEYS, sorted(data)
    manifest = load_any(launch)  # `plan`/`up` on the launch file read the same manifest
    assert manifest.network.ssh_from != ("10.0.0.0/8",) and manifest.tags == {}


@pytest.mark.parametrize("case", CASES, ids=list(CASES))
def test_nothing_from_a_launch_file_becomes_a_key(case: str, tmp_path: Path) -> None:
    name, text = CASES[case]
    launch = tmp_path / name
    launch.write_text(text, newline="")
    out = tmp_path / "out" / "fogiac.yaml"
    out.parent.mkdir()
    result = CliRunner().invoke(app, ["import", str(launch), "--out", str(out)])
    assert result.exit_code in (0, 1) and "Traceback" not in result.output, result.output
    if result.exit_code == 0:
        _check_written(out.read_text(), launch)
        assert all(line.isprintable() for line in result.output.splitlines()), result.output
    else:  # refused: each problem one line naming the launch file, and no manifest
        assert not out.exists()
        with pytest.raises(ManifestError) as info:
            load_any(launch)
        assert all(p.startswith(f"{launch}:") and p.isprintable() for p in info.value.problems), info.value.problems
        assert str(out) not in result.output


def test_an_escape_in_a_name_is_written_escaped_not_invalid_yaml(tmp_path: Path) -> None:
    """Item 13: a robot-local node named with an escape character imports; the header shows it as ``\\x1b``."""
    launch = tmp_path / "robot.launch.py"
    launch.write_text(_py("local", "cam\x1b[31m"))
    out = tmp_path / "fogiac.yaml"
    result = CliRunner().invoke(app, ["import", str(launch), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "#   - cam\\x1b[31m/cam_node" in out.read_text().splitlines()


def test_problems_name_the_launch_file_and_node_line_not_a_file_never_written(tmp_path: Path) -> None:
    """Item 13: a problem found validating what was converted names the launch file and the node's line."""
    launch = tmp_path / "robot.launch"
    launch.write_text(_xml("none", "") .replace("g4dn.xlarge", "g4dn.xlrge"))  # type: ignore[union-attr]
    out = tmp_path / "fogiac.yaml"
    result = CliRunner().invoke(app, ["import", str(launch), "--out", str(out)])
    assert result.exit_code == 1 and not out.exists()
    assert result.output.strip() == (
        f"{launch}:3: imported as nodes[0].machine: 'g4dn.xlrge' is not a known instance type; did you mean "
        "'g4dn.xlarge'?")
    launch_py = tmp_path / "robot.launch.py"
    launch_py.write_text(_py("image", "x").replace("'docker run -e K='x' img ' + 'x'", "'docker run Bad:Image'"))
    result = CliRunner().invoke(app, ["import", str(launch_py), "--out", str(out)])
    assert result.exit_code == 1 and not out.exists()
    assert result.output.startswith(f"{launch_py}:9: imported as nodes[1].image: "), result.output


@settings(max_examples=300, deadline=None)
@given(st.lists(st.text(), max_size=4), st.dictionaries(st.text(), st.text(), max_size=4), st.lists(st.text()))
def test_whatever_the_strings_the_text_reads_back_as_written(header: list[str], env: dict[str, str],
                                                             words: list[str]) -> None:
    """The writer both importers use: any header lines stay that many comment lines, and any strings
    (keys too) read back as the same strings, under the same keys, and nothing else."""
    data = {"name": "n", "nodes": [{"env": {FromLaunch(k): FromLaunch(v) for k, v in env.items()},
                                    "command": [FromLaunch(w) for w in words]}]}
    text = dump([f"#   - {line}" for line in header], data)
    lines = text.split("\n")
    assert all(line.startswith("#   - ") for line in lines[:len(header)]) and lines[len(header)] == "name: n"
    assert yaml.safe_load(text) == {"name": "n", "nodes": [{"env": env, "command": words}]}
