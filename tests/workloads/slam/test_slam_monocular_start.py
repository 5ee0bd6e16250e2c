"""The monocular start: the homography/essential choice by score, and the refusal of a weak start.

Synthetic two-view matches (exact projections plus half a pixel of noise) with known motion:
general scenes take the essential matrix and recover the motion, a plane takes the homography
and recovers it too, and pure rotation or too few points are refused rather than mapped.
"""

from __future__ import annotations

import numpy as np

from workloads.slam.camera import Intrinsics
from workloads.slam.geometry import angle_of, inverse, make, transform
from workloads.slam.monocular import MIN_POINTS, _candidates, choose_start


def _rot_y(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


def _views(world: np.ndarray, pose_b: np.ndarray, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K, uv in camera a at the origin, uv in camera b at ``pose_b``), points seen by both only."""
    k = Intrinsics.fr1()
    rng = np.random.default_rng(seed)
    uv_a, z_a = k.project(world)
    uv_b, z_b = k.project(transform(inverse(pose_b), world))
    seen = (z_a > 0) & (z_b > 0) & k.inside(uv_a) & k.inside(uv_b)
    noise = rng.normal(0, 0.5, (2, int(seen.sum()), 2))
    return k.matrix(), uv_a[seen] + noise[0], uv_b[seen] + noise[1]


def _scene(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-1.5, 1.5, n), rng.uniform(-1.0, 1.0, n), rng.uniform(1.5, 4.0, n)])


def test_a_general_scene_takes_the_essential_matrix_and_its_motion() -> None:
    truth = make(_rot_y(4.0), np.array([0.25, 0.02, 0.05]))
    k, a, b = _views(_scene(400), truth)
    chosen = _candidates(k, a, b)
    assert chosen is not None and chosen[0] == "essential"
    start = choose_start(k, a, b, np.zeros(len(a), np.int64))
    assert start is not None
    pose_b, _, good = start
    assert good.sum() >= 0.8 * len(a)
    assert np.degrees(angle_of(pose_b[:3, :3].T @ truth[:3, :3])) < 0.5
    direction = truth[:3, 3] / np.linalg.norm(truth[:3, 3])
    assert float(pose_b[:3, 3] @ direction) > np.cos(np.radians(3.0))  # unit length: the scale is unknown


def test_a_plane_takes_the_homography_and_its_motion() -> None:
    rng = np.random.default_rng(1)
    plane = np.column_stack([rng.uniform(-1.5, 1.5, 400), rng.uniform(-1.0, 1.0, 400), np.full(400, 2.0)])
    truth = make(_rot_y(-5.0), np.array([-0.3, 0.0, 0.05]))
    k, a, b = _views(plane, truth, seed=1)
    chosen = _candidates(k, a, b)
    assert chosen is not None and chosen[0] == "homography"
    start = choose_start(k, a, b, np.zeros(len(a), np.int64))
    assert start is not None
    pose_b, points, good = start
    assert np.degrees(angle_of(pose_b[:3, :3].T @ truth[:3, :3])) < 1.0
    direction = truth[:3, 3] / np.linalg.norm(truth[:3, 3])
    assert float(pose_b[:3, 3] @ direction) > np.cos(np.radians(5.0))
    # The points lie on one plane again (up to the unknown scale): z proportional, x-z spread flat.
    z = points[good, 2]
    assert np.std(z) / np.mean(z) < 0.02


def test_pure_rotation_is_refused() -> None:
    k, a, b = _views(_scene(400, seed=2), make(_rot_y(6.0), np.zeros(3)), seed=2)
    assert choose_start(k, a, b, np.zeros(len(a), np.int64)) is None


def test_too_little_parallax_is_refused() -> None:
    k, a, b = _views(_scene(400, seed=3), make(_rot_y(1.0), np.array([0.03, 0.0, 0.0])), seed=3)
    assert choose_start(k, a, b, np.zeros(len(a), np.int64)) is None


def test_too_few_points_are_refused() -> None:
    truth = make(_rot_y(4.0), np.array([0.25, 0.02, 0.05]))
    k, a, b = _views(_scene(MIN_POINTS - 10, seed=4), truth, seed=4)
    assert choose_start(k, a, b, np.zeros(len(a), np.int64)) is None
