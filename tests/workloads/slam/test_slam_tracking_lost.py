"""Tracking around a lost frame, and the monocular start's waiting frames, on synthetic views.

A synthetic room of points with distinct descriptors is projected exactly (plus a little pixel
noise) from known poses, so tracking's own matching, PnP and trust checks run on real arrays
without rendering. Regressions:

- after a lost frame, the relocalised pose must not make a velocity with the lost frame's
  placeholder pose (the motion model's guess): that velocity sent the next prediction 16 degrees
  off on the rendered turn sequence and the trust check refused the next frames for good;
- in monocular, the frames between the start's two views are placed once the start's map exists
  (a forward or turning start waits tens of frames, a trajectory without them misses that much
  of its extent).
"""

from __future__ import annotations

import numpy as np

from workloads.slam.camera import Intrinsics
from workloads.slam.features import Features
from workloads.slam.geometry import angle_of, inverse, make, transform
from workloads.slam.monocular import MAX_WAIT_FRAMES
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


def test_monocular_places_the_frames_the_start_waited_for() -> None:
    world = World(seed=1)
    tracker = Tracker(world.k, mono=True)
    poses = [make(_rot_y(0.2 * i), np.array([0.012 * i, 0.0, 0.0])) for i in range(20)]
    started = None
    for i, pose in enumerate(poses):
        r = tracker.track(world.view(i, pose, depth=False))
        if started is None and r.tracked:
            started = i
    assert started is not None and started >= 4, "the start should need a few frames of parallax"
    trajectory = tracker.trajectory()
    assert len(trajectory) == len(poses)  # the waiting frames (and the reference) too
    assert tracker.placed_late == started
    # Right up to the start's scale: positions over the truth's, one ratio for all.
    est = trajectory.poses[1:, :3, 3]
    true = np.array([p[:3, 3] for p in poses[1:]])
    scale = float(np.median(np.linalg.norm(est, axis=1) / np.linalg.norm(true, axis=1)))
    assert np.abs(est / scale - true).max() < 0.01  # metres, over a 23 cm path
    for got, want in zip(trajectory.poses[:started], poses[:started], strict=True):  # the placed ones
        assert np.degrees(angle_of(got[:3, :3].T @ want[:3, :3])) < 0.5


def test_monocular_places_frames_from_before_a_replaced_reference() -> None:
    """A start that waits longer than a reference lasts (MAX_WAIT_FRAMES) still places the earlier
    frames: walking forward, they see a wider view of the same points (rendered forward sequence:
    the start came at frame 50 from a reference at frame 31, and frames 0-30 were lost for good)."""
    world = World(seed=2)
    tracker = Tracker(world.k, mono=True)
    # Standing still and turning a little (no parallax, no start) past a reference's lifetime, then walking.
    poses = [make(_rot_y(0.05 * i), np.zeros(3)) for i in range(MAX_WAIT_FRAMES + 4)]
    last = poses[-1]
    poses += [last @ make(np.eye(3), np.array([0.012 * i, 0.0, 0.0])) for i in range(1, 16)]
    started = None
    for i, pose in enumerate(poses):
        r = tracker.track(world.view(i, pose, depth=False))
        if started is None and r.tracked:
            started = i
    assert started is not None and started > MAX_WAIT_FRAMES + 4
    assert tracker.placed_late == started
    assert len(tracker.trajectory()) == len(poses)
