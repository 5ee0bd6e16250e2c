"""The Sim(3) pose graph undoes a monocular run's scale drift from one loop edge.

A synthetic loop: keyframes on a circle, tracked with a map scale that shrinks by 3% per
keyframe (what bigloop's monocular run does), so the estimated circle spirals inwards and its
end misses its start. One loop edge (the similarity the two ends' matched points give) and the
pose graph must bring the trajectory's shape back: aligned error and extent near the truth.
"""

from __future__ import annotations

import cv2
import numpy as np

from workloads.slam import sim3
from workloads.slam.geometry import ate_rmse

N, SHRINK = 24, 0.97


def _truth() -> list[np.ndarray]:
    poses = []
    for k in range(N):
        a = 2 * np.pi * k / N
        rotation, _ = cv2.Rodrigues(np.array([0.0, -a, 0.0]))
        poses.append(sim3.make(rotation, np.array([np.cos(a), 0.0, np.sin(a)]), 1.0))
    return poses


def _drifted(truth: list[np.ndarray]) -> list[np.ndarray]:
    """Each step's rotation right, its translation shrunk by the map scale at that keyframe."""
    poses = [truth[0]]
    for k in range(N - 1):
        rel = sim3.inverse(truth[k]) @ truth[k + 1]
        step = rel.copy()
        step[:3, 3] *= SHRINK ** k
        poses.append(poses[-1] @ step)
    return poses


def _positions(poses: list[np.ndarray]) -> np.ndarray:
    return np.array([p[:3, 3] for p in poses])


def test_a_loop_edge_corrects_scale_drift() -> None:
    truth = _truth()
    drifted = _drifted(truth)
    edges = [sim3.Edge(k, k + 1, sim3.inverse(drifted[k]) @ drifted[k + 1]) for k in range(N - 1)]
    # the loop: keyframe N-1 (in its drifted scale SHRINK**(N-2)) against keyframe 0 (scale 1),
    # from their matched points
    scale_last = SHRINK ** (N - 2)
    rng = np.random.default_rng(0)
    world = rng.uniform(-0.3, 0.3, (40, 3)) + truth[0][:3, 3] + np.array([0.0, 0.0, 0.5])
    in_first = (world - truth[0][:3, 3]) @ truth[0][:3, :3]
    in_last = scale_last * ((world - truth[-1][:3, 3]) @ truth[-1][:3, :3])
    loop = sim3.from_points(in_first, in_last)  # takes keyframe 0's frame into keyframe N-1's
    edges.append(sim3.Edge(N - 1, 0, loop, weight=10.0))

    before, _ = ate_rmse(_positions(drifted), _positions(truth), with_scale=True)
    corrected = sim3.optimise(drifted, edges)
    after, alignment = ate_rmse(_positions(corrected), _positions(truth), with_scale=True)

    assert before > 0.1  # the drift is real: over 10 cm on a 1 m circle
    assert after < 0.2 * before and after < 0.03
    aligned = alignment.apply(_positions(corrected))
    for axis in (0, 2):
        extent = np.ptp(aligned[:, axis]) / np.ptp(_positions(truth)[:, axis])
        assert 0.9 <= extent <= 1.1
    assert sim3.cost(corrected, edges) < 0.01 * sim3.cost(drifted, edges)
    assert np.allclose(corrected[0], drifted[0])  # the gauge: keyframe 0 stays put


def test_exp_log_and_inverse_round_trip() -> None:
    delta = np.array([0.1, -0.2, 0.3, 1.0, 2.0, -0.5, np.log(1.7)])
    s = sim3.exp(delta)
    assert np.allclose(sim3.log(s), delta)
    assert np.allclose(s @ sim3.inverse(s), np.eye(4))
    assert np.isclose(sim3.scale_of(s), 1.7)
