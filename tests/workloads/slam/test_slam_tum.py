"""TUM folders and trajectories: round trips, association, and errors a person can act on."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from fogiac.errors import WorkloadError
from workloads.slam.camera import Intrinsics
from workloads.slam.geometry import make, quat_to_rot
from workloads.slam.tum import Trajectory, associate, load_frame, read_sequence, read_trajectory, write_trajectory


def test_trajectory_round_trip(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    poses = np.array([make(quat_to_rot(rng.normal(size=4)), rng.normal(size=3)) for _ in range(20)])
    written = Trajectory(1305031102.175304 + np.arange(20) / 30.0, poses)
    write_trajectory(tmp_path / "traj.txt", written)
    back = read_trajectory(tmp_path / "traj.txt")
    assert back.stamps == pytest.approx(written.stamps, abs=1e-6)
    assert back.poses == pytest.approx(written.poses, abs=1e-6)


def test_associate_pairs_nearest_stamps_once() -> None:
    rgb = np.array([0.0, 0.033, 0.066, 0.5])
    depth = np.array([0.001, 0.030, 0.031, 0.07])
    assert associate(rgb, depth) == [(0, 0), (1, 2), (2, 3)]  # 0.5 has no depth within 20 ms


def test_rendered_folder_reads_back(desk: Path) -> None:
    seq = read_sequence(desk)
    assert len(seq.frames) == 120 and seq.groundtruth is not None and len(seq.groundtruth) == 120
    assert seq.intrinsics == Intrinsics.fr1().scaled(0.5)  # from the folder's camera.txt
    assert seq.rate_hz == pytest.approx(30.0, rel=1e-3)  # stamps are written to the microsecond
    grey, depth = load_frame(seq.frames[0], seq.intrinsics)
    assert grey.shape == depth.shape == (240, 320) and grey.dtype == np.uint8
    raw = cv2.imread(str(seq.frames[0].depth), cv2.IMREAD_UNCHANGED)
    assert raw.dtype == np.uint16
    assert depth == pytest.approx(raw / 5000.0)
    assert 0.5 < float(np.median(depth)) < 5.0


def test_real_tum_layout_without_camera_file_is_fr1(tmp_path: Path) -> None:
    (tmp_path / "rgb").mkdir()
    (tmp_path / "depth").mkdir()
    (tmp_path / "rgb.txt").write_text("# color images\n# file: 'rgbd_dataset_freiburg1_xyz.bag'\n"
                                      "1305031102.175304 rgb/1305031102.175304.png\n")
    (tmp_path / "depth.txt").write_text("1305031102.160407 depth/1305031102.160407.png\n")
    seq = read_sequence(tmp_path)
    assert seq.intrinsics == Intrinsics.fr1() and seq.groundtruth is None
    assert [f.rgb.name for f in seq.frames] == ["1305031102.175304.png"]
    assert read_sequence(tmp_path, intrinsics=Intrinsics.fr2()).intrinsics.fx == 520.9


def test_bad_lines_and_missing_files_name_the_place(tmp_path: Path) -> None:
    with pytest.raises(WorkloadError, match=r"rgb.txt: missing \(a TUM RGB-D folder has rgb.txt and depth.txt\)"):
        read_sequence(tmp_path)
    (tmp_path / "rgb.txt").write_text("# header\nnot-a-number rgb/x.png\n")
    (tmp_path / "depth.txt").write_text("")
    with pytest.raises(WorkloadError, match=r"rgb.txt:2: expected 'timestamp filename', got 'not-a-number rgb/x.png'"):
        read_sequence(tmp_path)
    (tmp_path / "traj.txt").write_text("1.0 2.0 3.0\n")
    with pytest.raises(WorkloadError, match=r"traj.txt:1: expected 'timestamp tx ty tz qx qy qz qw'"):
        read_trajectory(tmp_path / "traj.txt")
