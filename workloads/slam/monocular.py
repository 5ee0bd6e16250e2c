"""Monocular mode: two-view initialisation and new points by triangulation between keyframes.

Without depth the map starts from two frames far enough apart: the essential matrix (five-point
RANSAC) and its decomposition give the second camera's motion up to scale, the matches are
triangulated, and the map's scale is set so that the median depth is 1 (as ORB-SLAM2 does).
The trajectory is therefore evaluated up to scale (Sim(3) alignment).
"""

from __future__ import annotations

import cv2
import numpy as np

from workloads.slam.camera import Intrinsics
from workloads.slam.features import Features
from workloads.slam.geometry import inverse, make, transform
from workloads.slam.mapdata import Keyframe, Map

MIN_MATCHES = 100
MIN_POINTS = 80
MIN_PARALLAX_DEG = 1.0
MAX_WAIT_FRAMES = 30  # a reference frame older than this is replaced


def _matches(a: Features, b: Features, *, ratio: float) -> np.ndarray:
    """(M, 2) index pairs of mutual-best ORB matches passing the ratio test."""
    matcher = cv2.BFMatcher(cv2.NORM_HAMMING)
    if len(a) < 2 or len(b) < 2:
        return np.zeros((0, 2), np.int64)
    knn = matcher.knnMatch(a.desc, b.desc, k=2)
    pairs = [p[0] for p in knn if len(p) == 2 and p[0].distance < ratio * p[1].distance]
    best: dict[int, tuple[float, int]] = {}
    for m in pairs:
        if m.trainIdx not in best or m.distance < best[m.trainIdx][0]:
            best[m.trainIdx] = (m.distance, m.queryIdx)
    return np.array([(q, t) for t, (_, q) in best.items()], np.int64).reshape(-1, 2)


def _triangulate(k: np.ndarray, pose_a: np.ndarray, pose_b: np.ndarray, uv_a: np.ndarray, uv_b: np.ndarray,
                 octave: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(world points (N, 3), good (N,) bool): in front of both, reprojecting within 2 px, with parallax."""
    cw_a, cw_b = inverse(pose_a), inverse(pose_b)
    h = cv2.triangulatePoints(k @ cw_a[:3], k @ cw_b[:3], uv_a.T.astype(np.float64), uv_b.T.astype(np.float64))
    w = np.where(np.abs(h[3]) > 1e-12, h[3], 1e-12)
    points = (h[:3] / w).T
    good = np.ones(len(points), bool)
    for pose, uv in ((pose_a, uv_a), (pose_b, uv_b)):
        cam = transform(inverse(pose), points)
        z = np.where(cam[:, 2] > 1e-9, cam[:, 2], 1e-9)
        proj = (k @ (cam / z[:, None]).T).T[:, :2]
        good &= (cam[:, 2] > 0) & (np.linalg.norm(proj - uv, axis=1) < 2.0 * 1.2 ** octave)
    ray_a, ray_b = points - pose_a[:3, 3], points - pose_b[:3, 3]
    cos = (ray_a * ray_b).sum(axis=1) / (np.linalg.norm(ray_a, axis=1) * np.linalg.norm(ray_b, axis=1) + 1e-12)
    good &= cos < np.cos(np.radians(MIN_PARALLAX_DEG))
    return points, good


class Initialiser:
    """Holds a reference frame until a later one sees the same points from far enough away."""

    def __init__(self, intrinsics: Intrinsics) -> None:
        self.intrinsics = intrinsics
        self.reference: Features | None = None

    def try_initialise(self, m: Map, f: Features) -> bool:
        """True once ``m`` holds keyframes 0 (the reference) and 1 (``f``) and their points."""
        ref = self.reference
        if ref is None or f.index - ref.index > MAX_WAIT_FRAMES:
            self.reference = f
            return False
        pairs = _matches(ref, f, ratio=0.8)
        if len(pairs) < MIN_MATCHES:
            return False
        a, b = ref.uv[pairs[:, 0]].astype(np.float64), f.uv[pairs[:, 1]].astype(np.float64)
        if np.median(np.linalg.norm(a - b, axis=1)) < 0.03 * self.intrinsics.width:
            return False  # too little motion to see depth
        k = self.intrinsics.matrix()
        e, mask = cv2.findEssentialMat(a, b, k, method=cv2.RANSAC, prob=0.999, threshold=1.0)
        if e is None or e.shape != (3, 3):
            return False
        _, r, t, mask = cv2.recoverPose(e, a, b, k, mask=mask)
        pose_b = inverse(make(r, t.ravel()))  # recoverPose gives camera b from camera a
        inl = mask.ravel() > 0
        points, good = _triangulate(k, np.eye(4), pose_b, a, b, f.octave[pairs[:, 1]])
        good &= inl
        if good.sum() < MIN_POINTS:
            return False
        scale = 1.0 / float(np.median(points[good, 2]))
        pose_b[:3, 3] *= scale
        ids = m.points.add(points[good] * scale, f.desc[pairs[good, 1]], 0)
        kf_a = Keyframe(0, ref, np.eye(4), np.full(len(ref), -1, np.int64))
        kf_b = Keyframe(1, f, pose_b, np.full(len(f), -1, np.int64))
        kf_a.point_ids[pairs[good, 0]] = ids
        kf_b.point_ids[pairs[good, 1]] = ids
        m.keyframes.extend([kf_a, kf_b])
        return True


def triangulate_new_points(m: Map, intrinsics: Intrinsics, new: Keyframe, previous: Keyframe) -> int:
    """Match the two keyframes' features that have no point yet and add the good triangulations."""
    free_new = np.flatnonzero(new.point_ids < 0)
    free_old = np.flatnonzero(previous.point_ids < 0)
    sub_new = Features(new.features.index, new.features.stamp, new.features.uv[free_new],
                       new.features.octave[free_new], new.features.desc[free_new], new.features.depth[free_new])
    sub_old = Features(previous.features.index, previous.features.stamp, previous.features.uv[free_old],
                       previous.features.octave[free_old], previous.features.desc[free_old],
                       previous.features.depth[free_old])
    pairs = _matches(sub_old, sub_new, ratio=0.75)
    if len(pairs) == 0:
        return 0
    i_old, i_new = free_old[pairs[:, 0]], free_new[pairs[:, 1]]
    points, good = _triangulate(intrinsics.matrix(), previous.pose, new.pose, previous.features.uv[i_old],
                                new.features.uv[i_new], new.features.octave[i_new])
    ids = m.points.add(points[good], new.features.desc[i_new[good]], new.id)
    new.point_ids[i_new[good]] = ids
    previous.point_ids[i_old[good]] = ids
    return int(good.sum())
