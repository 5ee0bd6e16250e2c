"""``python -m workloads.grasp_planning predict``: JSON out, one-line errors, exit codes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from workloads.grasp_planning.camera import Intrinsics

REPO = Path(__file__).resolve().parents[3]


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "workloads.grasp_planning", *args], cwd=REPO, capture_output=True, text=True, timeout=120
    )


def test_scene_then_predict_prints_the_grasp_as_json(tmp_path: Path) -> None:
    depth = tmp_path / "depth.npy"
    made = _cli("scene", "--out", str(depth), "--seed", "3")
    assert made.returncode == 0, made.stderr
    opts = made.stdout.split()
    assert opts[::2] == ["--fx", "--fy", "--cx", "--cy"]
    out = _cli("predict", str(depth), *opts, "--json", "--device", "cpu")
    assert out.returncode == 0, out.stderr
    grasp = json.loads(out.stdout)
    assert set(grasp) == {"u", "v", "angle", "width", "quality", "position", "orientation"}
    image = np.load(depth)
    assert 0 <= grasp["u"] < image.shape[1] and 0 <= grasp["v"] < image.shape[0]
    assert 0 <= grasp["angle"] < np.pi and 0 <= grasp["quality"] <= 1 and 0 <= grasp["width"] <= 0.085
    # the position is the grasp pixel deprojected at the tip depth
    intr = Intrinsics(*(float(v) for v in opts[1::2]))
    z = grasp["position"][2]
    assert grasp["position"] == pytest.approx(list(intr.deproject(grasp["u"], grasp["v"], z)))
    assert 0.5 < z < 0.8


def test_missing_file_is_one_line_and_exit_1(tmp_path: Path) -> None:
    out = _cli("predict", str(tmp_path / "none.npy"), "--fx", "500", "--fy", "500", "--cx", "1", "--cy", "1", "--json")
    assert out.returncode == 1
    assert out.stdout == ""
    assert out.stderr == f"error: {tmp_path / 'none.npy'}: no such file\n"


def test_wrong_shape_is_one_line_and_exit_1(tmp_path: Path) -> None:
    bad = tmp_path / "rgb.npy"
    np.save(bad, np.zeros((40, 40, 3), dtype=np.float32))
    out = _cli("predict", str(bad), "--fx", "500", "--fy", "500", "--cx", "20", "--cy", "20", "--json")
    assert out.returncode == 1
    assert out.stderr == (
        f"error: {bad}: depth must be a 2-D array (H, W) with both sides >= 16, got shape (40, 40, 3)\n"
    )
