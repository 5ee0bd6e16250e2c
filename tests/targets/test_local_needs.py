"""Issue 35, items 16 and 24: a local sandbox runs its nodes with fogiac's own Python, so ``doctor --target
local`` checks what the manifest's workload nodes need there (their recipe's requirements installed, their
node module importable) and ``up --target local`` refuses in one line, naming the command that installs
what is missing, before anything starts (it used to start everything and leave the node dying with
``ModuleNotFoundError`` after half a minute, while doctor said ``ok``). And a virtual environment that hides
Debian's rospy is named as such, not as a missing package."""

from __future__ import annotations

import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from fogiac.cli import app
from fogiac.state import StackState
from fogiac.targets.local import needs
from tests.conftest import REPO
from tests.plugins.install import installed
from tests.plugins.tally import ENTRY_POINTS
from tests.plugins.tally import MANIFEST as TALLY

runner = CliRunner()
PLANNER = """\
name: planning
cloud: {provider: local}
nodes:
  - name: planner
    machine: c5.large
    workload: motion_planning
"""


def test_a_requirement_is_read_from_this_interpreters_metadata() -> None:
    assert not needs.unmet("typer>=0.12")  # fogiac's own
    assert needs.unmet("typer>=999")  # installed, at a version the line excludes
    assert needs.unmet("fogiac-no-such-distribution==1.0")


def test_doctor_names_a_workloads_missing_requirements_and_how_to_install_them(tmp_path: Path,
                                                                               _state_dir: Path) -> None:
    manifest = tmp_path / "counting.yaml"
    manifest.write_text(TALLY)
    with installed(tmp_path / "site", "fogiac_tally", ENTRY_POINTS):
        result = runner.invoke(app, ["doctor", str(manifest)], env={"COLUMNS": "400"})
    assert result.exit_code == 1, result.output
    line = next(line for line in result.output.splitlines() if "workload tally" in line)
    assert line == (f"FAIL workload tally (node counter): not installed for {sys.executable}, which runs local "
                    f"sandboxes' nodes: tally-counter==0.1; install: {sys.executable} -m pip install "
                    "tally-counter==0.1")


def test_up_refuses_before_anything_starts(tmp_path: Path, _state_dir: Path) -> None:
    manifest = tmp_path / "counting.yaml"
    manifest.write_text(TALLY)
    with installed(tmp_path / "site", "fogiac_tally", ENTRY_POINTS):
        result = runner.invoke(app, ["up", str(manifest), "--yes"], env={"COLUMNS": "400"})
    assert result.exit_code == 1, result.output
    assert result.output.startswith("error: workload tally (node counter): not installed for "), result.output
    assert result.output.count("\n") == 1 and "pip install tally-counter==0.1" in result.output
    assert not StackState("counting-dev").exists()  # nothing recorded, nothing started


def test_doctor_imports_a_shipped_workloads_node(tmp_path: Path, _state_dir: Path) -> None:
    pytest.importorskip("ompl")
    manifest = tmp_path / "planning.yaml"
    manifest.write_text(PLANNER)
    result = runner.invoke(app, ["doctor", str(manifest)], env={"COLUMNS": "400"})
    assert result.exit_code == 0, result.output
    assert ("ok   workload motion_planning (node planner): ompl==2.0.1, python-fcl>=0.7, trimesh>=4, numpy>=1.24, "
            "pycollada>=0.8 installed; workloads.motion_planning.node imports") in result.output


@pytest.mark.skipif(not (needs.SYSTEM_PACKAGES / "rospy").is_dir(), reason="needs Debian's python3-rospy")
def test_a_venv_without_system_site_packages_is_named(tmp_path: Path) -> None:
    """A real virtual environment made without --system-site-packages, seeing fogiac's dependencies only."""
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    deps = sysconfig.get_paths()["purelib"]
    pyyaml = tmp_path / "pyyaml"  # pyyaml, which fogiac's venv here takes from Debian's packages too
    pyyaml.mkdir()
    (pyyaml / "yaml").symlink_to(Path(yaml.__file__).parent)
    check = "from fogiac.targets.local.needs import rospy_check; c = rospy_check(); print(c.ok, c.detail)"
    done = subprocess.run([str(venv / "bin" / "python"), "-c", check],
                          env={"PYTHONPATH": f"{REPO}:{deps}:{pyyaml}", "PATH": "/usr/bin:/bin"},
                          capture_output=True, text=True, check=True)
    assert done.stdout.startswith(f"False installed in /usr/lib/python3/dist-packages, which this virtual "
                                  f"environment ({venv}) does not see: it was made without --system-site-packages"), \
        done.stdout
    assert "install python3-rospy" not in done.stdout
