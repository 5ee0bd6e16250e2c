"""Issue 35, item 24: a note about how the manifest reads (a replicated node's reply match that no stated
message type checks) is said by the commands that review the manifest (validate, plan, up), not by every
command that compiles it: ``down`` and ``status`` used to repeat it each time."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO

MANIFEST = """\
name: rep
cloud: {provider: local}
nodes:
  - name: planner
    machine: c5.large
    workload: motion_planning
    replicas: 2
    topics: {in: [/plan/request], out: [/plan/path]}
"""
NOTE = "warning: node planner: replies on /plan/path are matched by header.stamp, unchecked"


def fogiac(folder: Path, *args: str) -> str:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}
    done = subprocess.run([sys.executable, "-m", "fogiac", *args], cwd=folder, env=env, capture_output=True,
                          text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    return done.stderr


@pytest.mark.parametrize(("args", "said"), [(["validate"], True), (["plan"], True), (["down", "--yes"], False),
                                            (["status"], False)])
def test_the_note_is_the_reviewing_commands(args: list[str], said: bool, tmp_path: Path, _state_dir: Path) -> None:
    (tmp_path / "fogiac.yaml").write_text(MANIFEST)
    assert (NOTE in fogiac(tmp_path, *args)) is said
