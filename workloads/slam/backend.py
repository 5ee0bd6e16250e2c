"""The optimisations, on GTSAM: local bundle adjustment and the pose graph after a loop closes.

Why GTSAM rather than g2o: both ship cp311 wheels, but GTSAM's Python API is maintained with the
library (4.3.0, numpy in and out, ``GenericStereoFactor3D`` for the RGB-D observation ORB-SLAM2
uses), where g2opy is a third-party binding. GTSAM holds the GIL while it optimises (measured: two
threads take twice as long as one), so the optimisations run in their own processes
(``system.py``). Jobs and answers are plain arrays so that they pickle cheaply.

RGB-D observations are stereo measurements with a virtual baseline, as in ORB-SLAM2: the right
image's column ``u - fx b / depth`` ties a point's depth to the sensor's, with the uncertainty of
a stereo pair, growing with the square of the depth. The baseline is chosen so that a one-pixel
measurement sigma means a depth sigma of ``DEPTH_NOISE`` z^2 (a structured-light sensor's order):
with ORB-SLAM2's TUM setting (bf 40 px) depth was so loose next to the reprojections that the first
two-keyframe adjustment slid the second keyframe 6 cm along the scale-like direction (measured on a
rendered sequence). Monocular observations are projections.
Every observation has a Huber kernel; those still above the 95% chi-square bound after
optimising are reported as outliers for tracking to drop.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L, X

from workloads.slam import sim3
from workloads.slam.camera import Intrinsics
from workloads.slam.features import SCALE_FACTOR

DEPTH_NOISE = 0.005  # depth sigma per metre squared, per pixel of measurement sigma


def baseline_m(k: Intrinsics) -> float:
    """The virtual stereo baseline: disparity noise of sqrt(2) px is a depth sigma of DEPTH_NOISE z^2."""
    return float(np.sqrt(2.0) / (DEPTH_NOISE * k.fx))


CHI2_MONO, CHI2_STEREO = 5.991, 7.815  # 95% bounds for 2 and 3 degrees of freedom


@dataclass(frozen=True)
class BundleJob:
    epoch: int
    kf_ids: np.ndarray  # (K,)
    poses: np.ndarray  # (K, 4, 4) camera-to-world
    fixed: np.ndarray  # (K,) bool: keyframes that anchor the window and do not move
    point_ids: np.ndarray  # (P,)
    positions: np.ndarray  # (P, 3)
    obs_kf: np.ndarray  # (O,) index into kf_ids
    obs_pt: np.ndarray  # (O,) index into point_ids
    obs_uv: np.ndarray  # (O, 2)
    obs_depth: np.ndarray  # (O,) metres, 0 for a monocular observation
    obs_octave: np.ndarray  # (O,)
    intrinsics: Intrinsics
    iterations: int = 8


@dataclass(frozen=True)
class BundleResult:
    epoch: int
    kf_ids: np.ndarray
    poses: np.ndarray
    point_ids: np.ndarray
    positions: np.ndarray
    outliers: np.ndarray  # (M, 2) (keyframe id, point id) observations to drop
    seconds: float


def bundle_adjust(job: BundleJob) -> BundleResult:
    start = time.perf_counter()
    k = job.intrinsics
    mono_cal = gtsam.Cal3_S2(k.fx, k.fy, 0.0, k.cx, k.cy)
    b = baseline_m(k)
    stereo_cal = gtsam.Cal3_S2Stereo(k.fx, k.fy, 0.0, k.cx, k.cy, b)
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    for i, pose in enumerate(job.poses):
        values.insert(X(i), gtsam.Pose3(pose))
        if job.fixed[i]:
            graph.add(gtsam.NonlinearEqualityPose3(X(i), gtsam.Pose3(pose)))
    for j, p in enumerate(job.positions):
        values.insert(L(j), gtsam.Point3(*p))
    huber2 = gtsam.noiseModel.mEstimator.Huber.Create(np.sqrt(CHI2_MONO))
    huber3 = gtsam.noiseModel.mEstimator.Huber.Create(np.sqrt(CHI2_STEREO))
    sigmas = SCALE_FACTOR ** job.obs_octave.astype(float)
    right = job.obs_uv[:, 0] - k.fx * b / np.where(job.obs_depth > 0, job.obs_depth, 1.0)
    for o in range(len(job.obs_kf)):
        a, b, (u, v) = X(int(job.obs_kf[o])), L(int(job.obs_pt[o])), job.obs_uv[o]
        if job.obs_depth[o] > 0:
            noise = gtsam.noiseModel.Robust.Create(huber3, gtsam.noiseModel.Isotropic.Sigma(3, sigmas[o]))
            graph.add(gtsam.GenericStereoFactor3D(gtsam.StereoPoint2(u, right[o], v), noise, a, b, stereo_cal))
        else:
            noise = gtsam.noiseModel.Robust.Create(huber2, gtsam.noiseModel.Isotropic.Sigma(2, sigmas[o]))
            graph.add(gtsam.GenericProjectionFactorCal3_S2(gtsam.Point2(u, v), noise, a, b, mono_cal))
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(job.iterations)
    try:
        result = gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()
    except RuntimeError:  # an indeterminate system (a point seen once, at no depth): keep the input
        result = values
    poses = np.array([result.atPose3(X(i)).matrix() for i in range(len(job.poses))])
    positions = np.array([result.atPoint3(L(j)) for j in range(len(job.positions))]).reshape(-1, 3)
    outliers = _outliers(job, poses, positions)
    return BundleResult(job.epoch, job.kf_ids, poses, job.point_ids, positions, outliers,
                        time.perf_counter() - start)


def _outliers(job: BundleJob, poses: np.ndarray, positions: np.ndarray) -> np.ndarray:
    k, b = job.intrinsics, baseline_m(job.intrinsics)
    world_to_cam = np.linalg.inv(poses)[job.obs_kf]
    p = np.einsum("nij,nj->ni", world_to_cam[:, :3, :3], positions[job.obs_pt]) + world_to_cam[:, :3, 3]
    z = np.where(p[:, 2] > 1e-6, p[:, 2], 1e-6)
    du = k.fx * p[:, 0] / z + k.cx - job.obs_uv[:, 0]
    dv = k.fy * p[:, 1] / z + k.cy - job.obs_uv[:, 1]
    stereo = job.obs_depth > 0
    dr = np.where(stereo, (k.fx * (p[:, 0] - b) / z + k.cx)
                  - (job.obs_uv[:, 0] - k.fx * b / np.where(stereo, job.obs_depth, 1.0)), 0.0)
    chi2 = (du**2 + dv**2 + dr**2) / (SCALE_FACTOR ** (2.0 * job.obs_octave))
    bad = (p[:, 2] <= 0) | (chi2 > np.where(stereo, CHI2_STEREO, CHI2_MONO))
    return np.column_stack([job.kf_ids[job.obs_kf[bad]], job.point_ids[job.obs_pt[bad]]])


@dataclass(frozen=True)
class PoseGraphJob:
    epoch: int
    kf_ids: np.ndarray  # (K,)
    poses: np.ndarray  # (K, 4, 4) camera-to-world before correction
    edges: np.ndarray  # (E, 2) indices into kf_ids
    relative: np.ndarray  # (E, 4, 4) measured pose of edge's second keyframe in its first's frame
    loop_edges: np.ndarray  # (E,) bool
    similarity: bool = False  # monocular: loop edges' ``relative`` are similarities, the graph Sim(3)


@dataclass(frozen=True)
class PoseGraphResult:
    epoch: int
    kf_ids: np.ndarray
    before: np.ndarray
    after: np.ndarray
    seconds: float


def optimise_pose_graph(job: PoseGraphJob) -> PoseGraphResult:
    """Spread a loop's correction over the keyframes: odometry edges hold their shape, loops pull.
    With ``job.similarity`` the graph is Sim(3) (:func:`optimise_sim3_graph`), else SE(3) on GTSAM."""
    start = time.perf_counter()
    if job.similarity:
        return optimise_sim3_graph(job)
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    for i, pose in enumerate(job.poses):
        values.insert(X(i), gtsam.Pose3(pose))
    graph.add(gtsam.NonlinearEqualityPose3(X(0), gtsam.Pose3(job.poses[0])))
    odometry = gtsam.noiseModel.Diagonal.Sigmas(np.array([0.01, 0.01, 0.01, 0.01, 0.01, 0.01]))
    loop = gtsam.noiseModel.Diagonal.Sigmas(np.array([0.005, 0.005, 0.005, 0.005, 0.005, 0.005]))
    for (a, b), rel, is_loop in zip(job.edges, job.relative, job.loop_edges, strict=True):
        graph.add(gtsam.BetweenFactorPose3(X(int(a)), X(int(b)), gtsam.Pose3(rel), loop if is_loop else odometry))
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(30)
    result = gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()
    after = np.array([result.atPose3(X(i)).matrix() for i in range(len(job.poses))])
    return PoseGraphResult(job.epoch, job.kf_ids, job.poses, after, time.perf_counter() - start)


LOOP_WEIGHT = 10.0  # a loop edge against an odometry edge in the Sim(3) graph


def optimise_sim3_graph(job: PoseGraphJob) -> PoseGraphResult:
    """The monocular pose graph: nodes are keyframe similarities (scale 1 to start with), odometry
    edges the keyframes' current relative poses (scale 1: they hold the local shape and scale),
    loop edges the loops' similarities, which carry the scale the map drifted by around the loop;
    keyframe 0 is held. The answer's ``after`` are similarities (:func:`workloads.slam.sim3.correct_map`
    turns them into a map correction). On our own numpy optimiser (``sim3.py``, tested on a synthetic
    scale drift); GTSAM 4.3's ``BetweenFactorSimilarity3`` would serve too (not tried)."""
    start = time.perf_counter()
    poses = [p.copy() for p in job.poses]
    edges = [sim3.Edge(int(a), int(b), rel, LOOP_WEIGHT if is_loop else 1.0)
             for (a, b), rel, is_loop in zip(job.edges, job.relative, job.loop_edges, strict=True)]
    after = np.array(sim3.optimise(poses, edges, iterations=30))
    return PoseGraphResult(job.epoch, job.kf_ids, job.poses, after, time.perf_counter() - start)
