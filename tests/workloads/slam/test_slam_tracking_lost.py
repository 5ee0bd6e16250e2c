"""Tracking around a lost frame, on synthetic views.

A synthetic room of points with distinct descriptors is projected exactly (plus a little pixel
noise) from known poses, so tracking's own matching, PnP and trust checks run on real arrays
without rendering. Regression: after a lost frame, the relocalised pose must not make a
velocity with the lost frame's placeholder pose (the motion model's guess): that velocity sent
the next prediction 16 degrees off on the rendered turn sequence and the trust check refused the
next frames for good.
"""

from __future__ import annotations

import numpy as np

from workloads.slam.camera import Intrinsics
from workloads.slam.features import Features
from workloads.slam.geometry import inverse, make, transform
from workloads.slam.tracking import Tracker


def _rot_y(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


class World:
    def __init__(self, n: int = 1500, seed: int = 0) -> None:
        rng = np.random.default_rng(seed)
        self.points = np.column_stack([rng.uniform(-3, 3, n), rng.uniform(-1.5, 1.5, n), rng.uniform(1.5, 4.0, n)])
        self.desc = rng.integers(0, 256, (n, 32), dtype=np.uint8)
        self.rng = rng
        self.k = Intrinsics.fr1()

    def view(self, index: int, pose: np.ndarray, *, depth: bool) -> Features:
        uv, z = self.k.project(transform(inverse(pose), self.points))
        seen = np.flatnonzero((z > 0) & self.k.inside(uv))
        uv = uv[seen] + self.rng.normal(0, 0.3, (len(seen), 2))
        d = z[seen] if depth else np.zeros(len(seen))
        return Features(index, float(index), uv.astype(np.float32), np.zeros(len(seen), np.int32),
                        self.desc[seen], d.astype(np.float32))

    def noise(self, index: int) -> Features:
        """A frame that matches nothing in the map (a blurred or blocked view)."""
        uv = self.rng.uniform(0, 640, (300, 2)).astype(np.float32)
        uv[:, 1] *= 0.75
        return Features(index, float(index), uv, np.zeros(300, np.int32),
                        self.rng.integers(0, 256, (300, 32), dtype=np.uint8), np.zeros(300, np.float32))


def test_the_frame_after_a_relocalisation_is_tracked() -> None:
    world = World()
    tracker = Tracker(world.k)
    step = make(_rot_y(0.5), np.array([0.01, 0.0, 0.0]))
    pose = np.eye(4)
    results = []
    for i in range(6):  # tracked at a steady motion: the motion model holds a velocity
        results.append(tracker.track(world.view(i, pose, depth=True)))
        pose = pose @ step
    assert all(r.tracked for r in results)
    assert not tracker.track(world.noise(6)).tracked  # lost: its pose is the motion model's guess
    # The camera turned meanwhile: the relocalised pose lies far from that guess.
    pose = pose @ step @ make(_rot_y(12.0), np.array([0.05, 0.0, 0.0]))
    back = tracker.track(world.view(7, pose, depth=True))
    assert back.tracked
    for i in range(8, 11):  # and on from there at the steady motion
        pose = pose @ step
        r = tracker.track(world.view(i, pose, depth=True))
        assert r.tracked, f"frame {i} after the relocalisation was refused"
        assert r.pose is not None
        assert np.linalg.norm(r.pose[:3, 3] - pose[:3, 3]) < 0.01
