"""Issue 33: ``up --plan`` applies exactly what was reviewed. A saved plan binds the manifest, every file
``up`` pushes, the machine catalogue, its own content, the stack, target and environment, and the
record it was planned against; each change is refused in one line naming it, before anything runs.
An unchanged plan still applies (a real ``up`` on the local target), and then is stale."""

from __future__ import annotations

import gzip
import json
import os
import shutil
import subprocess
import sys
from importlib import resources
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fogiac import deployment
from fogiac.cli import app
from fogiac.errors import PlanError
from fogiac.manifest.schema import load_manifest
from fogiac.plan.compile import compile_plan
from fogiac.plan.saved import check_applies, check_saved_plan
from fogiac.procs import free_port
from fogiac.targets.aws.catalogue import SHIPPED
from fogiac.targets.aws.manifest import user_catalogue
from tests.conftest import REPO

runner = CliRunner()
AGAIN = "; run `fogiac plan --out` again"

MANIFEST = """\
name: bound
cloud: {provider: local}
nodes:
  - name: arm
    machine: t3.small
    launch: {package: fogtest, file: talker.launch, workspace: ws, env_script: ws/setup.sh,
             requirements: ws/requirements.txt}
"""


@pytest.fixture
def project(tmp_path: Path) -> Path:
    """A manifest whose node pushes a workspace, an env script and a requirements file."""
    (tmp_path / "ws" / "src" / "fogtest").mkdir(parents=True)
    (tmp_path / "ws" / "src" / "fogtest" / "talker.py").write_text("print('hello')\n")
    (tmp_path / "ws" / "setup.sh").write_text("#!/bin/sh\ntrue\n")
    (tmp_path / "ws" / "requirements.txt").write_text("numpy==1.26.4\n")
    manifest = tmp_path / "fogiac.yaml"
    manifest.write_text(MANIFEST)
    return manifest


def _plan_out(manifest: Path) -> Path:
    saved = manifest.parent / "plan.json"
    result = runner.invoke(app, ["plan", str(manifest), "--out", str(saved)])
    assert result.exit_code == 0, result.output
    return saved


def _up(manifest: Path, saved: Path) -> list[str]:
    """``up --plan``'s refusal: its one line (nothing may have started: it refuses before)."""
    result = runner.invoke(app, ["up", str(manifest), "--yes", "--plan", str(saved)])
    assert result.exit_code == 1, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), lines
    return [lines[0].removeprefix("error: ")]


def _edit_workspace(project: Path) -> str:
    (project.parent / "ws" / "src" / "fogtest" / "talker.py").write_text("print('hello')\nimport os\n")
    return f"node arm's workspace {project.parent / 'ws'} changed since the plan"


def _edit_env_script(project: Path) -> str:
    with (project.parent / "ws" / "setup.sh").open("a") as script:
        script.write("echo applied anyway\n")  # what the issue saw run
    return f"node arm's env script {project.parent / 'ws' / 'setup.sh'} changed since the plan"


def _edit_requirements(project: Path) -> str:
    (project.parent / "ws" / "requirements.txt").write_text("numpy==1.26.4\nrequests==2.32.3\n")
    return f"node arm's requirements file {project.parent / 'ws' / 'requirements.txt'} changed since the plan"


def _refresh_catalogue(project: Path) -> str:
    """A catalogue refreshed after the review (``fogiac catalog update`` writes the user's own)."""
    raw = json.loads(gzip.decompress(resources.files("fogiac").joinpath(SHIPPED).read_bytes()))
    user_catalogue().parent.mkdir(parents=True, exist_ok=True)
    user_catalogue().write_bytes(gzip.compress(json.dumps(raw, indent=1).encode()))
    return "was made with another machine catalogue"


@pytest.mark.parametrize("change", [_edit_workspace, _edit_env_script, _edit_requirements, _refresh_catalogue])
def test_a_change_after_the_review_is_refused_naming_it(change, project: Path) -> None:  # type: ignore[no-untyped-def]
    saved = _plan_out(project)
    said = change(project)
    (line,) = _up(project, saved)
    assert said in line and line.endswith(AGAIN), line
    assert line.startswith(f"saved plan {saved}"), line


def test_a_hand_edited_plan_is_refused(project: Path) -> None:
    saved = _plan_out(project)
    doc = json.loads(saved.read_text())
    assert doc["hosts"]
    saved.write_text(json.dumps({**doc, "hosts": [], "nodes": []}, indent=2))
    assert _up(project, saved) == [f"saved plan {saved} was edited after `fogiac plan --out` wrote it (its content "
                                   f"no longer matches its digest){AGAIN}"]
    unbound = {k: v for k, v in doc.items() if k != "saved"}
    saved.write_text(json.dumps(unbound))
    assert _up(project, saved) == [f"saved plan {saved} binds nothing up can check (it has no `saved` section: "
                                   f"`fogiac plan --out` did not write it){AGAIN}"]


def test_a_plan_made_against_an_older_record_is_refused(project: Path) -> None:
    saved = _plan_out(project)
    plan = compile_plan(load_manifest(project))
    deployment.finish(plan, project, plan_digest="0" * 64)  # another member's up, since the review
    (line,) = _up(project, saved)
    assert line.startswith(f"saved plan {saved} was made against no record (nothing deployed) of stack bound-dev's "
                           f"record, which is now serial 1 (lineage "), line
    assert line.endswith(f"): it was applied or removed since{AGAIN}")
    again = _plan_out(project)  # planned against that record: it binds serial 1
    deployment.finish(plan, project, plan_digest="1" * 64)
    (line,) = _up(project, again)
    assert "made against serial 1 (lineage " in line and "which is now serial 2 (lineage " in line


def test_an_unchanged_plan_passes_and_under_the_lock_the_applied_document_must_match(project: Path) -> None:
    saved = _plan_out(project)
    plan = compile_plan(load_manifest(project))
    doc = check_saved_plan(saved, manifest=project, stack=plan.stack, target=plan.target, plan=plan)
    check_applies(saved, doc, {"stack": plan.stack, "plan_digest": doc["plan_digest"]})
    with pytest.raises(PlanError, match=rf"^saved plan {saved} is not what up would apply now \(plan digest "
                                        rf"{doc['plan_digest'][:12]} there, 000000000000 now\)"):
        check_applies(saved, doc, {"stack": plan.stack, "plan_digest": "0" * 64})


@pytest.mark.ros
@pytest.mark.skipif(shutil.which("roscore") is None, reason="needs Debian's ros-core (roscore)")
def test_an_unchanged_plan_applies_on_the_local_target_and_is_then_stale(tmp_path: Path, _state_dir: Path) -> None:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]),
           "ROS_MASTER_URI": f"http://127.0.0.1:{free_port()}", "ROS_HOSTNAME": "127.0.0.1", "COLUMNS": "200"}

    def fogiac(*argv: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "fogiac", *argv], cwd=tmp_path, env=env, capture_output=True,
                              text=True, timeout=300)

    assert fogiac("init", "--name", "reviewed").returncode == 0
    assert fogiac("plan", "--target", "local", "--out", "plan.json").returncode == 0
    try:
        applied = fogiac("up", "--target", "local", "--yes", "--start-edge-master", "--plan", "plan.json")
        assert applied.returncode == 0, applied.stdout + applied.stderr
        assert "applied: " in applied.stdout
        stale = fogiac("up", "--target", "local", "--yes", "--start-edge-master", "--plan", "plan.json")
        assert stale.returncode == 1
        assert stale.stderr.startswith("error: saved plan plan.json was made against no record (nothing deployed) "
                                       "of stack reviewed-dev's record, which is now serial "), stale.stderr
    finally:
        assert fogiac("down", "--target", "local", "--yes").returncode == 0
