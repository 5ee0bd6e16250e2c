"""Transforms, quaternions and Umeyama alignment against known answers."""

from __future__ import annotations

import numpy as np
import pytest

from workloads.slam.geometry import ate_rmse, inverse, make, quat_to_rot, rot_to_quat, transform, umeyama


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    return quat_to_rot(q / np.linalg.norm(q))


def test_quaternion_round_trip_and_sign() -> None:
    rng = np.random.default_rng(1)
    for _ in range(50):
        r = _random_rotation(rng)
        q = rot_to_quat(r)
        assert q[3] >= 0 and np.linalg.norm(q) == pytest.approx(1.0)
        assert quat_to_rot(q) == pytest.approx(r, abs=1e-9)
    assert rot_to_quat(np.diag([1.0, -1.0, -1.0])) == pytest.approx([1.0, 0.0, 0.0, 0.0])  # 180 degrees about x


def test_inverse_undoes_transform() -> None:
    rng = np.random.default_rng(2)
    t = make(_random_rotation(rng), rng.normal(size=3))
    points = rng.normal(size=(10, 3))
    assert transform(inverse(t), transform(t, points)) == pytest.approx(points)


@pytest.mark.parametrize("with_scale", [False, True])
def test_umeyama_recovers_a_known_transform(with_scale: bool) -> None:
    rng = np.random.default_rng(3)
    source = rng.normal(size=(40, 3))
    rotation, translation, scale = _random_rotation(rng), np.array([0.5, -1.0, 2.0]), 2.5 if with_scale else 1.0
    target = scale * source @ rotation.T + translation
    a = umeyama(source, target, with_scale=with_scale)
    assert (a.rotation, a.translation, a.scale) == (pytest.approx(rotation), pytest.approx(translation),
                                                     pytest.approx(scale))
    rmse, _ = ate_rmse(source, target, with_scale=with_scale)
    assert rmse == pytest.approx(0.0, abs=1e-9)


def test_ate_without_scale_keeps_a_scale_error() -> None:
    rng = np.random.default_rng(4)
    truth = rng.normal(size=(30, 3))
    assert ate_rmse(0.5 * truth, truth, with_scale=False)[0] > 0.1
    assert ate_rmse(0.5 * truth, truth, with_scale=True)[0] == pytest.approx(0.0, abs=1e-9)


def test_umeyama_needs_three_positions() -> None:
    with pytest.raises(ValueError, match="at least 3 positions, got 2"):
        umeyama(np.zeros((2, 3)), np.zeros((2, 3)), with_scale=False)
