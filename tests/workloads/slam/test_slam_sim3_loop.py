"""A monocular loop closes through the Sim(3) pose graph, from the loop's matched points to the map.

A synthetic map whose true similarity is known: keyframes on a 1 m circle whose map scale shrinks
by 3% per keyframe (what bigloop's monocular run did before it kept its scale), so the last
keyframe sees the first one's points in units 0.52 times the first's. The loop detector's check
(:meth:`LoopDetector._verify`, PnP on the matched keyframe's points) must give the similarity the
two keyframes really differ by (scale included: an earlier wiring got 2400-8500), and the whole
loop-closing path (tracking's graph job, the similarities put on its loop edges, the Sim(3) graph
in the back end, the map correction) must bring keyframes, frames and map points back to the
truth's shape.
"""

from __future__ import annotations

import cv2
import numpy as np

from workloads.slam import sim3
from workloads.slam.backend import PoseGraphResult, optimise_pose_graph
from workloads.slam.camera import Intrinsics
from workloads.slam.features import Features
from workloads.slam.geometry import ate_rmse, inverse, transform
from workloads.slam.loop import LoopDetector, LoopKeyframe
from workloads.slam.mapdata import FrameRecord, Keyframe
from workloads.slam.system import _with_similarities
from workloads.slam.tracking import Tracker

N, SHRINK, POINTS = 24, 0.97, 120
K = Intrinsics()


def _circle(angle: float) -> np.ndarray:
    rotation, _ = cv2.Rodrigues(np.array([0.0, -angle, 0.0]))  # looking along the circle's tangent
    return sim3.make(rotation, np.array([np.cos(angle), 0.0, np.sin(angle)]), 1.0)


def _scale(k: int) -> float:
    """Map units per metre at keyframe ``k``: the drift so far."""
    return SHRINK ** max(k - 1, 0)


def _drifted(truth: list[np.ndarray]) -> list[np.ndarray]:
    poses = [truth[0]]
    for k in range(len(truth) - 1):
        step = inverse(truth[k]) @ truth[k + 1]
        step[:3, 3] *= SHRINK ** k
        poses.append(poses[-1] @ step)
    return poses


def _world_points(pose: np.ndarray, rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` points 1-2.5 m in front of ``pose``, inside its image."""
    depth = rng.uniform(1.0, 2.5, n)
    uv = rng.uniform([40, 40], [K.width - 40, K.height - 40], (n, 2))
    return transform(pose, K.backproject(uv, depth))


def _features(index: int, uv: np.ndarray, desc: np.ndarray) -> Features:
    return Features(index, float(index), uv.astype(np.float32), np.zeros(len(uv), np.int64), desc,
                    np.zeros(len(uv), np.float32))


def _project(pose: np.ndarray, world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    cam = transform(inverse(pose), world)
    return cam, np.column_stack([K.fx * cam[:, 0] / cam[:, 2] + K.cx, K.fy * cam[:, 1] / cam[:, 2] + K.cy])


def _loop_keyframes(truth: list[np.ndarray], rng: np.random.Generator) -> tuple[LoopKeyframe, LoopKeyframe]:
    """Keyframe 0 and keyframe N-1 seeing the same points, each with them in its own frame and units."""
    world = _world_points(truth[0], rng, POINTS)
    desc = rng.integers(0, 256, (POINTS, 32), dtype=np.uint8)
    cam0, uv0 = _project(truth[0], world)
    cam_last, uv_last = _project(truth[-1], world)
    seen = (cam_last[:, 2] > 0.2) & (uv_last[:, 0] > 0) & (uv_last[:, 0] < K.width) & (uv_last[:, 1] > 0) \
        & (uv_last[:, 1] < K.height)
    order = rng.permutation(int(seen.sum()))  # the query's features in another order than the match's
    query = LoopKeyframe(N - 1, uv_last[seen][order], desc[seen][order], _scale(N - 1) * cam_last[seen][order])
    match = LoopKeyframe(0, uv0, desc, _scale(0) * cam0)
    return query, match


def test_the_loop_similarity_is_the_true_one() -> None:
    truth = [_circle(2 * np.pi * k / N) for k in range(N)]
    query, match = _loop_keyframes(truth, np.random.default_rng(1))
    loop = LoopDetector(K)._verify(query, match, 1.0)  # noqa: SLF001
    assert loop is not None and loop.similarity is not None
    assert loop.scale_pairs >= 40
    # the query keyframe's frame (query units) in the matched one's (metres): truth, scaled back
    expected = inverse(truth[0]) @ truth[-1] @ np.diag([1 / _scale(N - 1)] * 3 + [1.0])
    assert np.isclose(sim3.scale_of(loop.similarity), 1 / _scale(N - 1), rtol=1e-3)
    assert np.allclose(loop.similarity, expected, atol=1e-3)
    # the rigid part is PnP's answer as before
    assert np.allclose(loop.relative, inverse(truth[0]) @ truth[-1], atol=1e-3)


def test_the_query_s_own_new_points_do_not_set_the_scale() -> None:
    """A keyframe's own just-triangulated points come out too close (bigloop-1: 0.30 of the true
    depth where its other points sat at 0.40): the loop's scale is read from the others."""
    truth = [_circle(2 * np.pi * k / N) for k in range(N)]
    query, match = _loop_keyframes(truth, np.random.default_rng(4))
    fresh = np.arange(len(query.points)) % 2 == 0
    biased = query.points.copy()
    biased[fresh] *= 0.7
    detector = LoopDetector(K)
    marked = detector._verify(LoopKeyframe(query.id, query.uv, query.desc, biased, fresh), match, 1.0)  # noqa: SLF001
    unmarked = detector._verify(LoopKeyframe(query.id, query.uv, query.desc, biased), match, 1.0)  # noqa: SLF001
    assert marked is not None and marked.similarity is not None
    assert unmarked is not None and unmarked.similarity is not None
    assert np.isclose(sim3.scale_of(marked.similarity), 1 / _scale(N - 1), rtol=1e-3)
    assert 0 < marked.scale_pairs <= int((~fresh).sum())
    assert not np.isclose(sim3.scale_of(unmarked.similarity), 1 / _scale(N - 1), rtol=0.05)


def test_too_few_points_at_the_query_give_a_rigid_loop() -> None:
    truth = [_circle(2 * np.pi * k / N) for k in range(N)]
    query, match = _loop_keyframes(truth, np.random.default_rng(2))
    sparse = query.points.copy()
    sparse[sim3.MIN_SCALE_PAIRS - 1:] = np.nan  # the query's new points not triangulated yet
    loop = LoopDetector(K)._verify(LoopKeyframe(query.id, query.uv, query.desc, sparse), match, 1.0)  # noqa: SLF001
    assert loop is not None and loop.similarity is not None
    assert np.isclose(sim3.scale_of(loop.similarity), 1.0)


def _rms(error: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(error**2, axis=1))))


def test_monocular_loop_closing_removes_scale_drift() -> None:
    rng = np.random.default_rng(3)
    truth = [_circle(2 * np.pi * k / N) for k in range(N)]
    drifted = _drifted(truth)
    tracker = Tracker(K, mono=True)
    m = tracker.map
    true_points, frame_truth = [], []
    for k in range(N):
        world = _world_points(truth[k], rng, 8)
        cam = transform(inverse(truth[k]), world)
        ids = m.points.add(transform(drifted[k], _scale(k) * cam), np.zeros((8, 32), np.uint8), k)
        true_points.append(world)
        feats = _features(k, np.zeros((8, 2)), np.zeros((8, 32), np.uint8))
        m.keyframes.append(Keyframe(k, feats, drifted[k].copy(), ids.copy()))
        half = _circle(2 * np.pi * (k + 0.5) / N)  # a frame halfway to the next keyframe
        relative = inverse(truth[k]) @ half
        relative[:3, 3] *= _scale(k)
        m.frames += [FrameRecord(2 * k, 2.0 * k, k, np.eye(4), True),
                     FrameRecord(2 * k + 1, 2.0 * k + 1, k, relative, True)]
        frame_truth += [truth[k][:3, 3], half[:3, 3]]

    _, drift_alignment = ate_rmse(np.array([p[:3, 3] for p in tracker.trajectory().poses]), np.array(frame_truth),
                                  with_scale=True)
    points_before = _rms(drift_alignment.apply(m.points.pos[:m.points.count]) - np.concatenate(true_points))
    query, match = _loop_keyframes(truth, rng)
    loop = LoopDetector(K)._verify(query, match, 1.0)  # noqa: SLF001
    assert loop is not None
    job = _with_similarities(tracker.pose_graph_job(loop), tracker.loops)
    assert job.similarity
    result = optimise_pose_graph(job)
    rigid = sim3.correct_map(m, result.before, result.after)
    tracker.apply_pose_graph(PoseGraphResult(result.epoch, result.kf_ids, result.before, rigid, result.seconds))

    positions = np.array([p[:3, 3] for p in tracker.trajectory().poses])
    before, _ = ate_rmse(np.array([drifted[k][:3, 3] for k in range(N)]), np.array([t[:3, 3] for t in truth]),
                         with_scale=True)
    after, alignment = ate_rmse(positions, np.array(frame_truth), with_scale=True)
    assert before > 0.1  # the drift is real: over 10 cm on a 1 m circle
    assert after < 0.03
    for axis in (0, 2):
        aligned = alignment.apply(positions)[:, axis]
        assert 0.95 <= np.ptp(aligned) / np.ptp(np.array(frame_truth)[:, axis]) <= 1.05
    # every point followed its keyframe's similarity, scale included
    points_after = _rms(alignment.apply(m.points.pos[:m.points.count]) - np.concatenate(true_points))
    assert points_after < 0.3 * points_before
    assert np.allclose(m.keyframes[0].pose, drifted[0])  # the gauge: keyframe 0 stays put
    for kf in m.keyframes:  # poses stay rigid: the scale went into the points and frames
        assert np.allclose(kf.pose[:3, :3] @ kf.pose[:3, :3].T, np.eye(3), atol=1e-6)
