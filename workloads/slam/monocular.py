"""Monocular mode: two-view initialisation and new points by triangulation between keyframes.

Without depth the map starts from two frames far enough apart. Two models compete, as in
ORB-SLAM: a homography (right for a planar scene or little parallax, where the essential matrix
is ill-conditioned and its decomposition picks a wrong motion) and the essential matrix (five-point
RANSAC). Each is scored by its matches' symmetric transfer (homography) or epipolar (essential)
errors under a chi-square cut, ``S = sum(th - d^2)`` over inliers; the homography is used when
``S_H / (S_H + S_F) > 0.45``. Its decomposition's up to four motions are told apart by the points
each triangulates in front of both cameras, and a start whose best motion is not clearly better
than its second, or that triangulates too few points or with too little parallax, is refused: a
weak start's map is wrong in shape and nothing later repairs it. The map's scale is set so that
the median depth is 1 (as ORB-SLAM2 does); the trajectory is evaluated up to scale (Sim(3)).
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
MIN_PARALLAX_DEG = 1.0  # the two-view start's per-point cut
# A new keyframe's points are cut at a lower parallax. The cut keeps a point by the parallax of
# its *estimated* position, and noise that puts a point too close also widens its parallax: where
# a keyframe pair's true parallax is near the cut (short baselines between keyframes), the points
# kept are the ones that came out too close. On the rendered bigloop (measured) the new points sat
# 4-60% closer than the map's, tracking against them shortened the next keyframe's baseline, that
# pair's points came out closer still, and the map's scale collapsed 40-fold within 16 keyframes.
NEW_POINT_MIN_PARALLAX_DEG = 0.5
MIN_MEDIAN_PARALLAX_DEG = 2.0  # a start whose points' median parallax is lower is refused
MIN_GOOD_SHARE = 0.5  # of the chosen model's inliers that must triangulate well
HOMOGRAPHY_RATIO = 0.45  # R_H above which the homography is used (ORB-SLAM's threshold)
CHI2_SCORE = 5.991  # chi-square, 2 dof, 95%: the score's cut (1 px sigma)
CHI2_EPIPOLAR = 3.841  # chi-square, 1 dof, 95%: a point-to-line distance's inlier cut
MAX_WAIT_FRAMES = 30  # a reference frame older than this is replaced
# Frames before the start placed against its map once it exists. Earlier references' frames count
# too: walking forward, the frames before the start see a wider view of the same scene (rendered
# forward sequence: the start came at frame 50, from a reference at frame 31).
MAX_PLACED_FRAMES = 60


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
                 octave: np.ndarray, *, min_parallax_deg: float = MIN_PARALLAX_DEG) -> tuple[np.ndarray, np.ndarray]:
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
    good &= cos < np.cos(np.radians(min_parallax_deg))
    return points, good


def homography_score(h: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray]:
    """(score, inlier mask) of ``b ~ H a``: transfer errors both ways, each direction cut at CHI2_SCORE."""
    def transfer(m: np.ndarray, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
        p = np.column_stack([src, np.ones(len(src))]) @ m.T
        w = np.where(np.abs(p[:, 2]) > 1e-12, p[:, 2], 1e-12)
        return ((p[:, :2] / w[:, None] - dst) ** 2).sum(axis=1)

    try:
        h_inv = np.linalg.inv(h)
    except np.linalg.LinAlgError:
        return 0.0, np.zeros(len(a), bool)
    d_b, d_a = transfer(h, a, b), transfer(h_inv, b, a)
    inl = (d_b < CHI2_SCORE) & (d_a < CHI2_SCORE)
    score = np.where(d_b < CHI2_SCORE, CHI2_SCORE - d_b, 0.0) + np.where(d_a < CHI2_SCORE, CHI2_SCORE - d_a, 0.0)
    return float(score[inl].sum()), inl


def epipolar_score(f_mat: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray]:
    """(score, inlier mask) of the fundamental matrix: point-to-epipolar-line distances both ways."""
    ha, hb = np.column_stack([a, np.ones(len(a))]), np.column_stack([b, np.ones(len(b))])
    line_b, line_a = ha @ f_mat.T, hb @ f_mat  # lines in b from a's points, in a from b's
    num = (hb * line_b).sum(axis=1) ** 2
    d_b = num / np.maximum(line_b[:, 0] ** 2 + line_b[:, 1] ** 2, 1e-12)
    d_a = num / np.maximum(line_a[:, 0] ** 2 + line_a[:, 1] ** 2, 1e-12)
    inl = (d_b < CHI2_EPIPOLAR) & (d_a < CHI2_EPIPOLAR)
    score = np.where(d_b < CHI2_EPIPOLAR, CHI2_SCORE - d_b, 0.0) + np.where(d_a < CHI2_EPIPOLAR, CHI2_SCORE - d_a, 0.0)
    return float(score[inl].sum()), inl


def _candidates(k: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[str, list[np.ndarray], np.ndarray] | None:
    """(model, candidate second-camera poses, inlier mask) of the model the scores choose."""
    e, e_mask = cv2.findEssentialMat(a, b, k, method=cv2.RANSAC, prob=0.999, threshold=1.0)
    h, _ = cv2.findHomography(a, b, cv2.RANSAC, np.sqrt(CHI2_SCORE))
    s_f, f_inl = 0.0, np.zeros(len(a), bool)
    if e is not None and e.shape == (3, 3):
        k_inv = np.linalg.inv(k)
        s_f, f_inl = epipolar_score(k_inv.T @ e @ k_inv, a, b)
    s_h, h_inl = (0.0, np.zeros(len(a), bool)) if h is None else homography_score(h, a, b)
    if s_h + s_f <= 0:
        return None
    if s_h / (s_h + s_f) > HOMOGRAPHY_RATIO:
        assert h is not None
        _, rotations, translations, _ = cv2.decomposeHomographyMat(h, k)
        # x_b = R x_a + t: camera b from camera a, the pose of b in a's (the world's) frame inverted
        return "homography", [inverse(make(r, t.ravel())) for r, t in zip(rotations, translations, strict=True)], h_inl
    assert e is not None
    _, r, t, _ = cv2.recoverPose(e, a, b, k, mask=e_mask.copy())
    return "essential", [inverse(make(r, t.ravel()))], f_inl


def choose_start(k: np.ndarray, a: np.ndarray, b: np.ndarray,
                 octave: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(second camera's pose, points, good mask) of a trustworthy two-view start, or None to wait.

    Refused when the best motion is ambiguous (its runner-up triangulates nearly as many points),
    triangulates fewer than MIN_POINTS or MIN_GOOD_SHARE of its model's inliers, or when its points'
    median parallax is under MIN_MEDIAN_PARALLAX_DEG."""
    chosen = _candidates(k, a, b)
    if chosen is None:
        return None
    _, poses, inl = chosen
    results = []
    for pose_b in poses:
        norm = float(np.linalg.norm(pose_b[:3, 3]))
        if norm < 1e-9:
            continue
        pose_b = pose_b.copy()
        pose_b[:3, 3] /= norm
        points, good = _triangulate(k, np.eye(4), pose_b, a, b, octave)
        good &= inl
        results.append((int(good.sum()), pose_b, points, good))
    if not results:
        return None
    results.sort(key=lambda r: -r[0])
    count, pose_b, points, good = results[0]
    if count < MIN_POINTS or count < MIN_GOOD_SHARE * int(inl.sum()):
        return None
    if len(results) > 1 and results[1][0] > 0.75 * count:
        return None  # two motions explain the matches about as well: wait for more parallax
    ray_a, ray_b = points[good], points[good] - pose_b[:3, 3]
    cos = (ray_a * ray_b).sum(axis=1) / (np.linalg.norm(ray_a, axis=1) * np.linalg.norm(ray_b, axis=1) + 1e-12)
    if np.degrees(np.median(np.arccos(np.clip(cos, -1.0, 1.0)))) < MIN_MEDIAN_PARALLAX_DEG:
        return None
    return pose_b, points, good


class Initialiser:
    """Holds a reference frame until a later one sees the same points from far enough away."""

    def __init__(self, intrinsics: Intrinsics) -> None:
        self.intrinsics = intrinsics
        self.reference: Features | None = None
        # Frames that waited for the start, earlier references included: the tracker places them
        # once the start's map exists (the newest MAX_PLACED_FRAMES of them, about 48 KB each).
        self.waited: list[Features] = []

    def try_initialise(self, m: Map, f: Features) -> bool:
        """True once ``m`` holds keyframes 0 (the reference) and 1 (``f``) and their points."""
        ref = self.reference
        if ref is None or f.index - ref.index > MAX_WAIT_FRAMES:
            if ref is not None:
                self.waited.append(ref)
            self.reference = f
            self.waited = self.waited[-MAX_PLACED_FRAMES:]
            return False
        if not self._start(m, ref, f):
            self.waited = [*self.waited, f][-MAX_PLACED_FRAMES:]
            return False
        return True

    def _start(self, m: Map, ref: Features, f: Features) -> bool:
        pairs = _matches(ref, f, ratio=0.8)
        if len(pairs) < MIN_MATCHES:
            return False
        a, b = ref.uv[pairs[:, 0]].astype(np.float64), f.uv[pairs[:, 1]].astype(np.float64)
        if np.median(np.linalg.norm(a - b, axis=1)) < 0.03 * self.intrinsics.width:
            return False  # too little motion to see depth
        k = self.intrinsics.matrix()
        start = choose_start(k, a, b, f.octave[pairs[:, 1]])
        if start is None:
            return False
        pose_b, points, good = start
        scale = 1.0 / float(np.median(points[good, 2]))
        pose_b[:3, 3] *= scale
        ids = m.points.add(points[good] * scale, f.desc[pairs[good, 1]], 0)
        kf_a = Keyframe(0, ref, np.eye(4), np.full(len(ref), -1, np.int64))
        kf_b = Keyframe(1, f, pose_b, np.full(len(f), -1, np.int64))
        kf_a.point_ids[pairs[good, 0]] = ids
        kf_b.point_ids[pairs[good, 1]] = ids
        m.keyframes.extend([kf_a, kf_b])
        return True


# In monocular a new keyframe triangulates with the PAIR_KEYFRAMES keyframes before it, and its
# points are kept by the parallax each ray would have at the keyframe's median depth (a prior that
# a point's own noise does not move), cut at PRIOR_MIN_PARALLAX_DEG: the selection then keeps no
# more too-close points than too-far ones, whatever the pair's parallax (test_slam_new_points).
# Rendered turn sequences: in the swing keyframes come every 3-4 frames, 0.1-1% of the scene's
# depth apart, so the two nearest keyframes gave almost no new points and tracking was lost for
# 60 frames. Measured (system runs, turn-1, 28 Nov): before, 89/150 frames, x extent 0.62; prior
# cut 0.5 degrees with 2 keyframes 106/150, 4.7 cm, x 0.74; with 8, 141/150 but the map shrank in
# the swing (11.3 cm, z 0.51); with 4 at 0.7 degrees 141/150, 2.2 cm, x 0.99 z 1.09.
PAIR_KEYFRAMES = 4
PRIOR_MIN_PARALLAX_DEG = 0.7
# ... and with up to WIDE_KEYFRAMES older keyframes that look the same way (optical axes within
# WIDE_ANGLE_DEG) from WIDE_MIN_BASELINE to WIDE_MAX_BASELINE of its median depth away. A camera
# that swings back over what it saw moves on while it turns, but its keyframes in the swing come
# every few frames and are too close together for any pair to triangulate; with nothing new to
# track, the map ran out and the rest of the swing was lost (rendered turn-0, measured 28 Nov:
# keyframes 8-14 gave no new point, their map positions stalled 4-6 cm short of the truth, and
# frames 77-147 were lost). The keyframe that saw the same view on the way out is 0.3 m (11% of
# the depth) away.
WIDE_KEYFRAMES = 2
WIDE_ANGLE_DEG = 20.0
WIDE_MIN_BASELINE = 0.03
WIDE_MAX_BASELINE = 0.5


def _prior_parallax(k: np.ndarray, pose_a: np.ndarray, pose_b: np.ndarray, uv_b: np.ndarray,
                    depth: float) -> np.ndarray:
    """Parallax (degrees) each of ``b``'s rays would have against ``a`` at the prior ``depth``."""
    rays = np.column_stack([uv_b, np.ones(len(uv_b))]) @ np.linalg.inv(k).T  # z = 1 in b's camera
    at = transform(pose_b, rays * depth)
    ray_a, ray_b = at - pose_a[:3, 3], at - pose_b[:3, 3]
    cos = (ray_a * ray_b).sum(axis=1) / (np.linalg.norm(ray_a, axis=1) * np.linalg.norm(ray_b, axis=1) + 1e-12)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def median_depth(m: Map, kf: Keyframe) -> float | None:
    """Median depth, in ``kf``'s camera, of the map points it tracked (None without any in front)."""
    ids = kf.point_ids[kf.point_ids >= 0]
    if len(ids) == 0:
        return None
    z = transform(inverse(kf.pose), m.points.pos[ids])[:, 2]
    z = z[z > 0]
    return float(np.median(z)) if len(z) else None


def add_new_points(m: Map, intrinsics: Intrinsics, new: Keyframe) -> int:
    """Triangulate ``new`` (the newest keyframe) with the keyframes before it and those that saw the
    same view from a wider baseline; the number of points added."""
    prior = median_depth(m, new)
    pairs = [kf for kf in m.keyframes[-1 - PAIR_KEYFRAMES:] if kf.id != new.id][::-1]  # nearest first
    if prior is not None:
        wide = m.keyframes_in_view(new.pose, exclude={new.id, *(kf.id for kf in pairs)}, count=WIDE_KEYFRAMES,
                                   max_angle_deg=WIDE_ANGLE_DEG, max_distance=WIDE_MAX_BASELINE * prior,
                                   min_distance=WIDE_MIN_BASELINE * prior)
        pairs += [m.keyframes[k] for k in wide]
    return sum(triangulate_new_points(m, intrinsics, new, previous, prior) for previous in pairs)


def triangulate_new_points(m: Map, intrinsics: Intrinsics, new: Keyframe, previous: Keyframe,
                           prior_depth: float | None = None) -> int:
    """Match the two keyframes' features that have no point yet and add the good triangulations;
    with ``prior_depth`` (the new keyframe's median depth) kept by their rays' parallax at that depth."""
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
    k = intrinsics.matrix()
    uv_old, uv_new = previous.features.uv[i_old], new.features.uv[i_new]
    if prior_depth is not None:
        points, good = _triangulate(k, previous.pose, new.pose, uv_old, uv_new, new.features.octave[i_new],
                                    min_parallax_deg=0.0)
        good &= _prior_parallax(k, previous.pose, new.pose, uv_new.astype(np.float64),
                                prior_depth) >= PRIOR_MIN_PARALLAX_DEG
    else:  # no tracked point to take a depth from: cut by the estimate's own parallax
        points, good = _triangulate(k, previous.pose, new.pose, uv_old, uv_new, new.features.octave[i_new],
                                    min_parallax_deg=NEW_POINT_MIN_PARALLAX_DEG)
    ids = m.points.add(points[good], new.features.desc[i_new[good]], new.id)
    new.point_ids[i_new[good]] = ids
    previous.point_ids[i_old[good]] = ids
    return int(good.sum())
