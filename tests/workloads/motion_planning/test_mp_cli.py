"""``python -m workloads.motion_planning solve``: JSON out, exit 0 solved, 1 otherwise."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from tests.workloads.motion_planning.mp_support import CUBE_OBJ, PROBLEMS, REPO, write_cfg

from workloads.motion_planning import Pose, load_problem, path_is_collision_free


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (str(REPO), os.environ.get("PYTHONPATH", "")) if p)}
    return subprocess.run([sys.executable, "-m", "workloads.motion_planning", *args], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=120)


def test_solve_json() -> None:
    result = _run("solve", str(PROBLEMS / "easy.cfg"), "--cores", "2", "--time-limit", "20", "--seed", "4", "--json")
    assert result.returncode == 0, result.stderr
    doc = json.loads(result.stdout)
    assert doc["solved"] is True and doc["cores"] == 2 and doc["planner"] == "rrtconnect"
    assert doc["solve_time_s"] > 0 and doc["plan_time_s"] > 0
    assert set(doc["path"][0]) == {"x", "y", "z", "qx", "qy", "qz", "qw"}
    path = [Pose(**p) for p in doc["path"]]
    assert path_is_collision_free(load_problem(PROBLEMS / "easy.cfg"), path, resolution=0.01)


def test_unsolved_exits_1(tmp_path: Path) -> None:
    (tmp_path / "robot.obj").write_text(CUBE_OBJ)
    (tmp_path / "world.obj").write_text(CUBE_OBJ)
    cfg = write_cfg(tmp_path, problem={"start.x": "0"})  # the start overlaps the world cube
    result = _run("solve", str(cfg), "--cores", "1", "--time-limit", "1", "--json")
    assert result.returncode == 1
    doc = json.loads(result.stdout)
    assert (doc["solved"], doc["status"], doc["path"]) == (False, "invalid start", [])


def test_bad_input_is_one_line(tmp_path: Path) -> None:
    result = _run("solve", str(tmp_path / "none.cfg"), "--json")
    assert result.returncode == 1
    assert result.stdout == ""
    assert result.stderr == f"error: {tmp_path / 'none.cfg'}: problem file not found\n"
