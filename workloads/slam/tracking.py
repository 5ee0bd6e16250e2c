"""Tracking: each frame's pose against the local map, keyframe decisions, and the map's bookkeeping.

The tracker owns the map (``mapdata.Map``). It never optimises: it hands the back end
:class:`BundleJob` and :class:`PoseGraphJob` snapshots and applies their answers, in delta form
for loop corrections (so work tracking did in the meantime is kept) and only when still current
for bundle adjustments (a loop correction bumps the map's epoch; older answers are dropped).
``system.py`` decides where the jobs run; tests may run them in line.

Per frame (ORB-SLAM2's TrackWithMotionModel and TrackLocalMap in one step): predict the pose
with a constant-velocity model, project the local map's points (the recent keyframes' and those
of keyframes a closed loop joined them to), match descriptors only within a radius of each
projection, then PnP RANSAC and Levenberg-Marquardt refinement on the inliers.

A frame counts as tracked only when its pose is trustworthy: enough inliers, and (while the
previous frame was tracked) landing within ``max_jump`` of where the motion model put it. A
pose that jumps is more likely wrong than the camera is fast, and a wrong pose reported as
tracked (and made a keyframe) bends the map for good; so the run says it is lost instead, and
the next frames relocalise: their features are matched against every point of the map, and a
pose needs ``relocalise_inliers`` inliers before tracking resumes.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from workloads.slam import monocular
from workloads.slam.backend import BundleJob, BundleResult, PoseGraphJob, PoseGraphResult
from workloads.slam.camera import Intrinsics
from workloads.slam.features import Features
from workloads.slam.geometry import angle_of, from_rvec, inverse, to_rvec, transform
from workloads.slam.loop import Loop, LoopKeyframe
from workloads.slam.mapdata import FrameRecord, Keyframe, Map
from workloads.slam.tum import Trajectory

MAX_HAMMING = 64
POPCOUNT = np.array([bin(i).count("1") for i in range(256)], np.uint8)


def hamming(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise Hamming distances of two (N, 32) uint8 descriptor arrays."""
    if hasattr(np, "bitwise_count"):  # numpy >= 2.0: popcount on 64-bit words
        words = np.bitwise_xor(np.ascontiguousarray(a).view(np.uint64), np.ascontiguousarray(b).view(np.uint64))
        return np.bitwise_count(words).sum(axis=1, dtype=np.int32)
    return POPCOUNT[np.bitwise_xor(a, b)].sum(axis=1, dtype=np.int32)


def near_pairs(features: np.ndarray, points: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """(feature index, point index) of every pair closer than ``radius`` px, through a grid of radius-sized cells.

    Features are sorted by cell once and a table gives each cell's first feature, so each point's
    nine neighbouring cells are two lookups each (on the tracking thread, the system's serial stage).
    """
    if len(features) == 0 or len(points) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    fx, fy = (features[:, 0] // radius).astype(np.int64) + 1, (features[:, 1] // radius).astype(np.int64) + 1
    px, py = (points[:, 0] // radius).astype(np.int64) + 1, (points[:, 1] // radius).astype(np.int64) + 1
    cells_x = int(max(fx.max(), px.max())) + 2
    cells_y = int(max(fy.max(), py.max())) + 2
    fcell = fy * cells_x + fx
    order = np.argsort(fcell, kind="stable")
    first = np.searchsorted(fcell[order], np.arange(cells_x * cells_y + 1))
    feats, pts = [], []
    for dy in (-1, 0, 1):
        y = py + dy
        for dx in (-1, 0, 1):
            x = px + dx
            ok = (x >= 0) & (y >= 0)  # the +1 offset keeps every feature's cell at x, y >= 1
            cell = np.where(ok, y * cells_x + x, cells_x * cells_y)  # the last, empty entry for none
            lo = first[np.minimum(cell, cells_x * cells_y)]
            count = first[np.minimum(cell + 1, cells_x * cells_y)] - lo
            total = int(count.sum())
            if total == 0:
                continue
            ends = np.cumsum(count)
            offset = np.arange(total) - np.repeat(ends - count, count)
            feats.append(order[np.repeat(lo, count) + offset])
            pts.append(np.repeat(np.arange(len(points)), count))
    if not feats:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    feat, point = np.concatenate(feats), np.concatenate(pts)
    close = ((features[feat] - points[point]) ** 2).sum(axis=1) < radius * radius
    return feat[close], point[close]


def best_matches(feat: np.ndarray, point: np.ndarray, dist: np.ndarray, *, ratio: float) -> np.ndarray:
    """(feature, point) pairs: each point's nearest feature if clearly better than its second, each feature once."""
    order = np.argsort(point * 512 + dist, kind="stable")  # by point, then distance (at most 256)
    feat, point, dist = feat[order], point[order], dist[order]
    first = np.ones(len(point), bool)
    first[1:] = point[1:] != point[:-1]
    idx = np.flatnonzero(first)
    has_second = np.zeros(len(idx), bool)
    second = np.full(len(idx), np.iinfo(np.int32).max)
    nxt = idx + 1
    ok = nxt < len(point)
    ok[ok] = point[nxt[ok]] == point[idx[ok]]
    has_second[ok], second[ok] = True, dist[nxt[ok]]
    keep = (dist[idx] <= MAX_HAMMING) & (~has_second | (dist[idx] < ratio * second))
    idx = idx[keep]
    feat, point, dist = feat[idx], point[idx], dist[idx]
    by_feature = np.argsort(feat * 512 + dist, kind="stable")  # a feature claimed by several points keeps the closest
    feat, point = feat[by_feature], point[by_feature]
    unique = np.ones(len(feat), bool)
    unique[1:] = feat[1:] != feat[:-1]
    return np.column_stack([feat[unique], point[unique]]).astype(np.int64)


@dataclass(frozen=True)
class Config:
    features: int = 1000
    local_keyframes: int = 8  # recent keyframes whose points tracking matches against
    ba_window: int = 6  # keyframes a local bundle adjustment moves
    ba_iterations: int = 8
    final_ba_iterations: int = 20  # monocular: the whole map adjusted once the last frame is tracked
    min_inliers: int = 25
    search_radius_px: float = 12.0
    keyframe_max_gap: int = 15  # frames
    keyframe_translation: float = 0.08  # metres (map units in monocular)
    keyframe_rotation_deg: float = 8.0
    keyframe_inlier_ratio: float = 0.7  # of the inliers the last keyframe was tracked with
    loop_min_gap: int = 20  # keyframes between a loop's two ends
    max_jump: float = 0.15  # metres (map units in monocular) a pose may land from the motion model's prediction
    max_jump_deg: float = 10.0
    relocalise_inliers: int = 50  # inliers a pose found against the whole map needs after tracking was lost


@dataclass(frozen=True)
class TrackResult:
    pose: np.ndarray | None  # camera-to-world; None before the map exists
    tracked: bool
    inliers: int
    keyframe: bool


class Tracker:
    def __init__(self, intrinsics: Intrinsics, config: Config | None = None, *, mono: bool = False) -> None:
        self.intrinsics, self.config, self.mono = intrinsics, config or Config(), mono
        self.map = Map()
        self.loops: list[Loop] = []
        self.new_keyframes: list[int] = []  # created since the last bundle job was taken
        self._matcher = cv2.BFMatcher(cv2.NORM_HAMMING)
        self._last_ref, self._last_relative = -1, np.eye(4)
        self._velocity = np.eye(4)
        self._kf_inliers = 0
        self._since_keyframe = 0
        self._lost = 0  # frames since the last trustworthy pose
        self.placed_late = 0  # frames placed after they came (the monocular start's waiting frames)
        self._init: monocular.Initialiser | None = monocular.Initialiser(intrinsics) if mono else None

    # -- tracking ------------------------------------------------------------------------------
    @property
    def last_pose(self) -> np.ndarray:
        return self.map.keyframes[self._last_ref].pose @ self._last_relative

    def track(self, f: Features) -> TrackResult:
        if not self.map.keyframes:
            return self._initialise(f)
        previous = self.last_pose
        predicted = previous @ self._velocity
        relocalising = self._lost > 0
        if relocalising:  # lost: the whole map, not just what the last (untrusted) pose would see
            ids = self.map.point_ids_of(list(range(len(self.map.keyframes))))
        else:
            ids = self.map.point_ids_of(self._local_keyframes())
        pose, inliers = self._pose_against(f, ids, predicted, wide=relocalising)
        tracked = pose is not None and self._trustworthy(pose, predicted, len(inliers), relocalising)
        if not tracked:
            pose, inliers = predicted, np.zeros((0, 2), np.int64)
            self._velocity = np.eye(4)
            self._lost += 1
        else:
            assert pose is not None
            # After a lost frame, ``previous`` is the motion model's guess, not a pose: no velocity from it.
            self._velocity = np.eye(4) if relocalising else inverse(previous) @ pose
            self._lost = 0
        assert pose is not None
        ref = self.map.keyframes[-1]
        self._last_ref, self._last_relative = ref.id, inverse(ref.pose) @ pose
        self.map.frames.append(FrameRecord(f.index, f.stamp, ref.id, self._last_relative, tracked))
        self._since_keyframe += 1
        made = tracked and self._wants_keyframe(pose, ref.pose, len(inliers))
        if made:
            self._insert_keyframe(f, pose, inliers)
        return TrackResult(pose, tracked, len(inliers), made)

    def _trustworthy(self, pose: np.ndarray, predicted: np.ndarray, inliers: int, relocalising: bool) -> bool:
        """Enough inliers, and (while tracking) a pose near the motion model's prediction."""
        c = self.config
        if relocalising:
            return inliers >= c.relocalise_inliers
        if inliers < c.min_inliers:
            return False
        jump = inverse(predicted) @ pose
        return bool(float(np.linalg.norm(jump[:3, 3])) <= c.max_jump
                    and float(np.degrees(angle_of(jump[:3, :3]))) <= c.max_jump_deg)

    def _local_keyframes(self) -> list[int]:
        count = len(self.map.keyframes)
        local = set(range(max(0, count - self.config.local_keyframes), count))
        for k in list(local):
            for other in self.map.links.get(k, ()):
                local.update(range(max(0, other - 2), min(count, other + 3)))
        return sorted(local)

    def _pose_against(self, f: Features, ids: np.ndarray, predicted: np.ndarray,
                      *, wide: bool = False) -> tuple[np.ndarray | None, np.ndarray]:
        """(pose, (M, 2) inlier pairs of feature index and map point id) or (None, empty);
        ``wide``: match every feature against every point (relocalisation) from the start."""
        radius = self.config.search_radius_px
        pairs = np.zeros((0, 2), np.int64)
        for r in ((None,) if wide else (radius, 3 * radius, None)):  # widen the search while too few match
            pairs = self._search(f, ids, predicted, r)
            if len(pairs) >= 2 * self.config.min_inliers:
                break
        if len(pairs) < self.config.min_inliers:
            return None, pairs[:0]
        obj = self.map.points.pos[pairs[:, 1]]
        img = f.uv[pairs[:, 0]].astype(np.float64)
        scale = 1.2 ** f.octave[pairs[:, 0]]
        k = self.intrinsics.matrix()
        starts = [inverse(predicted)]  # refine from the motion model, and from RANSAC's answer
        ok, rvec, tvec, inl = cv2.solvePnPRansac(obj, img, k, None, iterationsCount=100, reprojectionError=4.0,
                                                 confidence=0.99, flags=cv2.SOLVEPNP_EPNP)
        if ok and inl is not None and len(inl) >= self.config.min_inliers:
            starts.append(from_rvec(rvec, tvec))
        best: tuple[np.ndarray | None, np.ndarray] = (None, pairs[:0])
        for start in starts:
            pose, good = self._refine(obj, img, scale, start)
            if len(good) > len(best[1]):
                best = (pose, pairs[good])
        return best

    def _refine(self, obj: np.ndarray, img: np.ndarray, scale: np.ndarray, cam_from_world: np.ndarray,
                ) -> tuple[np.ndarray, np.ndarray]:
        """Levenberg-Marquardt on the matches within reach of ``cam_from_world``, twice, tightening;
        (camera-to-world pose, indices of the matches within 3 px times their octave's scale)."""
        k = self.intrinsics.matrix()
        rvec, tvec = to_rvec(cam_from_world)
        for threshold in (8.0, 3.0):
            uv, z = self.intrinsics.project(transform(from_rvec(rvec, tvec), obj))
            good = np.flatnonzero((z > 0) & (np.linalg.norm(uv - img, axis=1) / scale < threshold))
            if len(good) < 6:
                return inverse(from_rvec(rvec, tvec)), good[:0]
            rvec, tvec = cv2.solvePnPRefineLM(obj[good], img[good], k, None, rvec.reshape(3, 1), tvec.reshape(3, 1))
        uv, z = self.intrinsics.project(transform(from_rvec(rvec, tvec), obj))
        good = np.flatnonzero((z > 0) & (np.linalg.norm(uv - img, axis=1) / scale < 3.0))
        return inverse(from_rvec(rvec, tvec)), good

    def _search(self, f: Features, ids: np.ndarray, pose: np.ndarray, radius: float | None) -> np.ndarray:
        """Descriptor matches (feature index, point id), within ``radius`` px of each point's projection."""
        if len(ids) == 0 or len(f) == 0:
            return np.zeros((0, 2), np.int64)
        if radius is None:
            return self._search_all(f, ids)
        uv, z = self.intrinsics.project(transform(inverse(pose), self.map.points.pos[ids]))
        visible = (z > 0) & self.intrinsics.inside(uv, margin=-radius)
        ids, uv = ids[visible], uv[visible]
        feat, point = near_pairs(f.uv, uv, radius)
        if len(feat) == 0:
            return np.zeros((0, 2), np.int64)
        dist = hamming(f.desc[feat], self.map.points.desc[ids[point]])
        return best_matches(feat, ids[point], dist, ratio=0.9)

    def _search_all(self, f: Features, ids: np.ndarray) -> np.ndarray:
        """Relocalisation's search: every feature against every local point, a stricter ratio test."""
        best: dict[int, tuple[float, int]] = {}
        for pair in self._matcher.knnMatch(f.desc, self.map.points.desc[ids], k=2):
            if len(pair) < 2 or pair[0].distance > MAX_HAMMING or pair[0].distance > 0.75 * pair[1].distance:
                continue
            m = pair[0]
            if m.trainIdx not in best or m.distance < best[m.trainIdx][0]:
                best[m.trainIdx] = (m.distance, m.queryIdx)
        return np.array([(q, ids[t]) for t, (_, q) in best.items()], np.int64).reshape(-1, 2)

    # -- keyframes -----------------------------------------------------------------------------
    def _wants_keyframe(self, pose: np.ndarray, ref_pose: np.ndarray, inliers: int) -> bool:
        c = self.config
        if self._since_keyframe >= c.keyframe_max_gap:
            return True
        if self._since_keyframe < 2:
            return False
        rel = inverse(ref_pose) @ pose
        return (inliers < c.keyframe_inlier_ratio * self._kf_inliers
                or float(np.linalg.norm(rel[:3, 3])) > c.keyframe_translation
                or np.degrees(angle_of(rel[:3, :3])) > c.keyframe_rotation_deg)

    def _insert_keyframe(self, f: Features, pose: np.ndarray, inliers: np.ndarray) -> Keyframe:
        point_ids = np.full(len(f), -1, np.int64)
        point_ids[inliers[:, 0]] = inliers[:, 1]
        kf = Keyframe(len(self.map.keyframes), f, pose, point_ids)
        self.map.keyframes.append(kf)
        if self.mono:
            monocular.add_new_points(self.map, self.intrinsics, kf)
        else:
            fresh = np.flatnonzero((point_ids < 0) & (f.depth > 0))
            cam = self.intrinsics.backproject(f.uv[fresh].astype(np.float64), f.depth[fresh].astype(np.float64))
            point_ids[fresh] = self.map.points.add(transform(pose, cam), f.desc[fresh], kf.id)
        self.new_keyframes.append(kf.id)
        self._kf_inliers = max(len(inliers), int((point_ids >= 0).sum() * 0.5))
        self._since_keyframe = 0
        self._last_ref, self._last_relative = kf.id, np.eye(4)
        return kf

    def _initialise(self, f: Features) -> TrackResult:
        if self._init is None:  # RGB-D: the first frame with enough depth is the map
            if int((f.depth > 0).sum()) < 3 * self.config.min_inliers:
                self.map.frames.append(FrameRecord(f.index, f.stamp, -1, np.eye(4), False))
                return TrackResult(None, False, 0, False)
            self._insert_keyframe(f, np.eye(4), np.zeros((0, 2), np.int64))
            self._kf_inliers = len(f)
        else:
            if not self._init.try_initialise(self.map, f):
                self.map.frames.append(FrameRecord(f.index, f.stamp, -1, np.eye(4), False))
                return TrackResult(None, False, 0, False)
            self.new_keyframes.extend([0, 1])
            self._place_waited(self._init.waited)
            self._init.waited = []
            self._last_ref, self._last_relative = 1, np.eye(4)
            self._kf_inliers = int((self.map.keyframes[1].point_ids >= 0).sum())
        self.map.frames.append(FrameRecord(f.index, f.stamp, self._last_ref, np.eye(4), True))
        return TrackResult(self.last_pose, True, self._kf_inliers, True)

    def _place_waited(self, waited: list[Features]) -> None:
        """Place the frames that waited for the start against the start's map.

        Most see the points the start triangulated, so each is located as a lost frame is
        relocalised: every feature against every point, PnP RANSAC, and trusted only with
        ``relocalise_inliers`` inliers (those that do not stay untracked). Their records, written
        untracked when they came, are rewritten: the trajectory has them, a live node published
        nothing for them. A forward or turning start waits 10-50 frames for enough parallax
        (rendered sequences), and a trajectory without them misses that much of the path's extent."""
        at = {r.index: j for j, r in enumerate(self.map.frames)}
        ref = self.map.keyframes[0].features
        if ref.index in at:  # the reference is keyframe 0 itself
            self.map.frames[at[ref.index]] = FrameRecord(ref.index, ref.stamp, 0, np.eye(4), True)
            self.placed_late += 1
        ids = self.map.point_ids_of([0, 1])
        for f in waited:
            pose, inliers = self._pose_against(f, ids, np.eye(4), wide=True)
            if pose is None or len(inliers) < self.config.relocalise_inliers or f.index not in at:
                continue
            self.map.frames[at[f.index]] = FrameRecord(f.index, f.stamp, 0, inverse(self.map.keyframes[0].pose) @ pose,
                                                       True)
            self.placed_late += 1

    # -- back end: jobs out, answers in ---------------------------------------------------------
    def bundle_job(self, *, whole: bool = False) -> BundleJob | None:
        """A local bundle adjustment around the newest keyframes, if any arrived since the last job;
        ``whole``: every keyframe and point of the map (the first keyframes fixed), whether or not."""
        if not self.new_keyframes and not whole:
            return None
        self.new_keyframes = []
        kfs = self.map.keyframes
        window = list(range(0 if whole else max(0, len(kfs) - self.config.ba_window), len(kfs)))
        if len(window) < 2:
            return None
        ids = self.map.point_ids_of(window)
        in_job = np.zeros(self.map.points.count, bool)
        in_job[ids] = True
        start = max(0, window[0] - 2 * self.config.ba_window)
        fixed = [k for k in range(start, window[0]) if in_job[kfs[k].point_ids[kfs[k].point_ids >= 0]].any()]
        members = fixed + window
        is_fixed = np.array([k in fixed for k in members])
        if not is_fixed.any():
            is_fixed[0] = True
        if self.mono and is_fixed.sum() < 2:
            is_fixed[1] = True
        index_of = np.full(self.map.points.count, -1, np.int64)
        index_of[ids] = np.arange(len(ids))
        obs_kf, obs_ft = [], []
        for i, k in enumerate(members):
            ft = np.flatnonzero(kfs[k].point_ids >= 0)
            ft = ft[in_job[kfs[k].point_ids[ft]]]
            obs_kf.append(np.full(len(ft), i))
            obs_ft.append(ft)
        o_kf = np.concatenate(obs_kf)
        o_pt = np.concatenate([index_of[kfs[k].point_ids[ft]] for k, ft in zip(members, obs_ft, strict=True)])
        feats = [kfs[k].features for k in members]
        uv = np.concatenate([feats[i].uv[ft] for i, ft in enumerate(obs_ft)]).astype(np.float64)
        depth = np.concatenate([feats[i].depth[ft] for i, ft in enumerate(obs_ft)]).astype(np.float64)
        octave = np.concatenate([feats[i].octave[ft] for i, ft in enumerate(obs_ft)])
        if self.mono:  # a point seen once has no depth: leave it out
            seen = np.bincount(o_pt, minlength=len(ids))
            keep = seen[o_pt] >= 2
            o_kf, o_pt, uv, depth, octave = o_kf[keep], o_pt[keep], uv[keep], depth[keep], octave[keep]
        return BundleJob(self.map.epoch, np.array(members), np.array([kfs[k].pose for k in members]), is_fixed,
                         ids, self.map.points.pos[ids].copy(), o_kf, o_pt, uv, depth, octave, self.intrinsics,
                         self.config.final_ba_iterations if whole else self.config.ba_iterations)

    def apply_bundle(self, result: BundleResult) -> bool:
        if result.epoch != self.map.epoch:
            return False
        newest = int(result.kf_ids[-1])
        delta = result.poses[-1] @ inverse(self.map.keyframes[newest].pose)
        for k, pose in zip(result.kf_ids, result.poses, strict=True):
            self.map.keyframes[int(k)].pose = pose
        # Keyframes made while the adjustment ran, and their points, move with the newest one in it:
        # they were placed against the map as it was, and would otherwise sit where it no longer is.
        for kf in self.map.keyframes[newest + 1:]:
            kf.pose = delta @ kf.pose
        pts = self.map.points
        later = np.flatnonzero(pts.ref[:pts.count] > newest)
        pts.pos[later] = transform(delta, pts.pos[later])
        self.map.points.pos[result.point_ids] = result.positions
        for k, pid in result.outliers:
            ids = self.map.keyframes[int(k)].point_ids
            ids[ids == pid] = -1
        return True

    def loop_keyframe(self, kf_id: int) -> LoopKeyframe:
        kf = self.map.keyframes[kf_id]
        points = np.full((len(kf.features), 3), np.nan)
        has = kf.point_ids >= 0
        points[has] = transform(inverse(kf.pose), self.map.points.pos[kf.point_ids[has]])
        return LoopKeyframe(kf.id, kf.features.uv, kf.features.desc, points)

    def pose_graph_job(self, loop: Loop) -> PoseGraphJob:
        """Odometry edges between each keyframe and its two predecessors, and every loop closed so far."""
        self.loops.append(loop)
        poses = np.array([kf.pose for kf in self.map.keyframes])
        edges, relative, is_loop = [], [], []
        for k in range(1, len(poses)):
            for back in (1, 2):
                if k - back >= 0:
                    edges.append((k - back, k))
                    relative.append(inverse(poses[k - back]) @ poses[k])
                    is_loop.append(False)
        for lp in self.loops:
            edges.append((lp.match, lp.query))
            relative.append(lp.relative)
            is_loop.append(True)
        return PoseGraphJob(self.map.epoch, np.arange(len(poses)), poses, np.array(edges), np.array(relative),
                            np.array(is_loop))

    def apply_pose_graph(self, result: PoseGraphResult) -> None:
        deltas = [after @ inverse(before) for before, after in zip(result.before, result.after, strict=True)]
        kfs = self.map.keyframes
        for kf in kfs:  # keyframes made while optimising move with the newest one in the job
            kf.pose = deltas[min(kf.id, len(deltas) - 1)] @ kf.pose
        pts = self.map.points
        refs = np.minimum(pts.ref[:pts.count], len(deltas) - 1)
        stacked = np.array(deltas)[refs]
        pts.pos[:pts.count] = np.einsum("nij,nj->ni", stacked[:, :3, :3], pts.pos[:pts.count]) + stacked[:, :3, 3]
        loop = self.loops[-1]
        self.map.links.setdefault(loop.query, set()).add(loop.match)
        self.map.epoch += 1
        self._velocity = np.eye(4)

    # -- results -------------------------------------------------------------------------------
    def trajectory(self) -> Trajectory:
        """Every tracked frame's pose, through its reference keyframe's final pose."""
        done = [r for r in self.map.frames if r.tracked and r.ref >= 0]
        poses = np.array([self.map.keyframes[r.ref].pose @ r.relative for r in done]).reshape(-1, 4, 4)
        return Trajectory(np.array([r.stamp for r in done]), poses)

    def map_points(self) -> np.ndarray:
        return self.map.points.pos[:self.map.points.count].copy()
