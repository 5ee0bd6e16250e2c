"""GTSAM back end on problems with known answers: bundle adjustment and the loop's pose graph."""

from __future__ import annotations

import numpy as np
import pytest

from workloads.slam.backend import BundleJob, PoseGraphJob, bundle_adjust, optimise_pose_graph
from workloads.slam.camera import Intrinsics
from workloads.slam.geometry import inverse, make, quat_to_rot, transform


def _pose(x: float, yaw: float) -> np.ndarray:
    return make(quat_to_rot(np.array([0.0, np.sin(yaw / 2), 0.0, np.cos(yaw / 2)])), np.array([x, 0.0, 0.0]))


def _job(k: Intrinsics, poses: np.ndarray, points: np.ndarray, start_poses: np.ndarray, start_points: np.ndarray,
         *, rgbd: bool, outlier: bool = False) -> BundleJob:
    obs_kf, obs_pt, uv, depth = [], [], [], []
    for i, pose in enumerate(poses):
        pix, z = k.project(transform(inverse(pose), points))
        seen = np.flatnonzero((z > 0) & k.inside(pix))
        obs_kf += [i] * len(seen)
        obs_pt += list(seen)
        uv.append(pix[seen])
        depth.append(z[seen] if rgbd else np.zeros(len(seen)))
    uv_all = np.concatenate(uv)
    if outlier:
        uv_all[0] += 40.0  # one gross mismatch
    n = len(obs_kf)
    fixed = np.zeros(len(poses), bool)
    fixed[:1 if rgbd else 2] = True
    return BundleJob(0, np.arange(len(poses)), start_poses, fixed, np.arange(len(points)), start_points,
                     np.array(obs_kf), np.array(obs_pt), uv_all, np.concatenate(depth), np.zeros(n, np.int32), k, 20)


@pytest.mark.parametrize("rgbd", [True, False])
def test_bundle_adjustment_recovers_poses_and_points(rgbd: bool) -> None:
    k = Intrinsics.fr1()
    rng = np.random.default_rng(5)
    poses = np.array([_pose(0.1 * i, 0.03 * i) for i in range(5)])
    points = rng.uniform([-1.5, -1.0, 2.0], [1.5, 1.0, 4.0], (200, 3))
    start_poses = poses.copy()
    start_poses[2:, :3, 3] += rng.normal(0, 0.02, (3, 3))
    start_points = points + rng.normal(0, 0.03, points.shape)
    result = bundle_adjust(_job(k, poses, points, start_poses, start_points, rgbd=rgbd, outlier=True))
    assert np.abs(result.poses[:, :3, 3] - poses[:, :3, 3]).max() < 2e-3
    # Noise-free observations from 3 cm off: RGB-D pins depth; monocular's depth converges slower.
    assert np.median(np.linalg.norm(result.positions - points, axis=1)) < (2e-3 if rgbd else 5e-3)
    assert result.outliers.tolist() == [[0, 0]]  # the gross mismatch, reported as (keyframe, point)


def test_pose_graph_spreads_a_loop_correction() -> None:
    n = 12
    truth = np.array([_pose(0.0, 2 * np.pi * i / n) @ make(np.eye(3), np.array([0.0, 0.0, -1.0])) for i in range(n)])
    drift = make(quat_to_rot(np.array([0.0, np.sin(0.01), 0.0, np.cos(0.01)])), np.array([0.02, 0.0, 0.0]))
    odometry = [inverse(truth[i - 1]) @ truth[i] @ drift for i in range(1, n)]
    estimate = [truth[0]]
    for step in odometry:
        estimate.append(estimate[-1] @ step)
    edges = [(i - 1, i) for i in range(1, n)] + [(0, n - 1)]
    relative = [*odometry, inverse(truth[0]) @ truth[n - 1]]
    job = PoseGraphJob(3, np.arange(n), np.array(estimate), np.array(edges), np.array(relative),
                       np.array([False] * (n - 1) + [True]))
    before = np.linalg.norm(np.array(estimate)[:, :3, 3] - truth[:, :3, 3], axis=1).max()
    result = optimise_pose_graph(job)
    after = np.linalg.norm(result.after[:, :3, 3] - truth[:, :3, 3], axis=1).max()
    assert result.epoch == 3 and after < before / 3
    assert result.after[0] == pytest.approx(truth[0])  # the first keyframe anchors the map
