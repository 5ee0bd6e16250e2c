"""The map tracking owns: keyframes, map points, and what each keyframe observes.

Map points carry a world position, one ORB descriptor and a reference keyframe (the one that
created them): when a loop closes, a point moves with its reference keyframe's correction, as in
ORB-SLAM2. Frames are stored relative to a keyframe, so the final trajectory follows every
correction the back end made after the frame was tracked.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workloads.slam.features import Features


@dataclass
class Keyframe:
    id: int
    features: Features
    pose: np.ndarray  # camera-to-world
    point_ids: np.ndarray  # (N,) map point seen at each feature, -1 for none


class Points:
    """Growable arrays of map points (positions, descriptors, reference keyframes)."""

    def __init__(self, capacity: int = 4096) -> None:
        self.pos = np.zeros((capacity, 3))
        self.desc = np.zeros((capacity, 32), np.uint8)
        self.ref = np.zeros(capacity, np.int64)
        self.count = 0

    def add(self, pos: np.ndarray, desc: np.ndarray, ref: int) -> np.ndarray:
        n = len(pos)
        while self.count + n > len(self.pos):
            self.pos = np.concatenate([self.pos, np.zeros_like(self.pos)])
            self.desc = np.concatenate([self.desc, np.zeros_like(self.desc)])
            self.ref = np.concatenate([self.ref, np.zeros_like(self.ref)])
        ids = np.arange(self.count, self.count + n)
        self.pos[ids], self.desc[ids], self.ref[ids] = pos, desc, ref
        self.count += n
        return ids


@dataclass
class FrameRecord:
    index: int
    stamp: float
    ref: int  # keyframe id
    relative: np.ndarray  # pose in the reference keyframe's frame
    tracked: bool


@dataclass
class Map:
    keyframes: list[Keyframe] = field(default_factory=list)
    points: Points = field(default_factory=Points)
    frames: list[FrameRecord] = field(default_factory=list)
    links: dict[int, set[int]] = field(default_factory=dict)  # keyframes joined by a closed loop
    epoch: int = 0  # bumped by each loop correction: back-end answers computed before it are stale

    def keyframes_in_view(self, pose: np.ndarray, *, exclude: set[int], count: int, max_angle_deg: float,
                          max_distance: float, min_distance: float = 0.0) -> list[int]:
        """Up to ``count`` keyframes not in ``exclude`` whose optical axis is within ``max_angle_deg``
        of ``pose``'s and whose centre is ``min_distance`` to ``max_distance`` from it, nearest in angle first."""
        older = [kf for kf in self.keyframes if kf.id not in exclude]
        if count <= 0 or not older:
            return []
        cos = np.array([kf.pose[:3, 2] for kf in older]) @ pose[:3, 2]
        dist = np.linalg.norm(np.array([kf.pose[:3, 3] for kf in older]) - pose[:3, 3], axis=1)
        ok = np.flatnonzero((cos >= np.cos(np.radians(max_angle_deg))) & (dist <= max_distance)
                            & (dist >= min_distance))
        return [older[i].id for i in ok[np.argsort(-cos[ok], kind="stable")][:count]]

    def point_ids_of(self, keyframe_ids: list[int]) -> np.ndarray:
        seen = [self.keyframes[k].point_ids for k in keyframe_ids]
        ids = np.concatenate(seen) if seen else np.zeros(0, np.int64)
        return np.unique(ids[ids >= 0])
