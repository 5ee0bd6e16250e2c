"""A monocular keyframe in a swing triangulates with the keyframe that saw its view from farther away.

Regression for the rendered turn-0 sequence: swinging back over what it saw on the way out, the
camera's keyframes came every few frames, too close together for any pair of the newest ones to
pass the parallax cut; no keyframe added a point, the map ran out and frames 77-147 were lost (x
extent 0.69 of the truth). The keyframe made on the way out, looking the same way, was 0.3 m
away. Synthetic keyframes with exact descriptors and one pixel of noise: four keyframes a few
millimetres apart give nothing, the older one looking the same way from 0.3 m gives points at
their true depth.
"""

from __future__ import annotations

import numpy as np

from tests.workloads.slam.test_slam_new_points import synthetic_keyframe
from workloads.slam.camera import Intrinsics
from workloads.slam.features import Features
from workloads.slam.geometry import inverse, make, transform
from workloads.slam.mapdata import Keyframe, Map
from workloads.slam.monocular import add_new_points


def test_a_swing_keyframe_triangulates_with_the_older_keyframe_that_saw_its_view() -> None:
    k, rng = Intrinsics.fr1(), np.random.default_rng(7)
    n = 900
    world = np.column_stack([rng.uniform(-1.0, 1.0, n), rng.uniform(-0.7, 0.7, n), rng.uniform(2.2, 2.8, n)])
    desc = rng.integers(0, 256, (n, 32), dtype=np.uint8)
    m = Map()
    tracked = np.arange(300)  # points the map has: the swing's keyframes tracked them
    ids = m.points.add(world[tracked], desc[tracked], 0)
    # keyframe 0: the same view from 0.3 m away, seen on the way out; 1-4 and the new 5: the swing
    # back, 2 mm apart (0.1% of the depth, as the stalled keyframes were)
    centres = [np.array([-0.3, 0.0, 0.0])] + [np.array([0.002 * i, 0.0, 0.0]) for i in range(5)]
    for kf_id, centre in enumerate(centres):
        kf = synthetic_keyframe(kf_id, k, make(np.eye(3), centre), world, desc, rng)
        kf.point_ids[tracked] = ids
        m.keyframes.append(kf)
    new = m.keyframes[-1]
    added = add_new_points(m, k, new)
    assert added > 300, f"the swing's keyframe added {added} points"
    kept = np.flatnonzero(new.point_ids >= 0)
    kept = kept[kept >= len(tracked)]
    depth = transform(inverse(new.pose), m.points.pos[new.point_ids[kept]])[:, 2]
    truth = transform(inverse(new.pose), world[kept])[:, 2]
    ratio = float(np.median(depth / truth))
    assert abs(ratio - 1.0) < 0.02, f"new points' median depth is {ratio:.3f} of the truth"


def test_keyframes_in_view_keep_to_the_view_and_the_baseline() -> None:
    """Only keyframes looking the same way, within the baseline band, nearest in angle first."""
    m = Map()
    empty = Features(0, 0.0, np.zeros((0, 2), np.float32), np.zeros(0, np.int32), np.zeros((0, 32), np.uint8),
                     np.zeros(0, np.float32))

    def yawed(deg: float, x: float) -> np.ndarray:
        a = np.radians(deg)
        return make(np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]), np.array([x, 0, 0]))

    for kf_id, (deg, x) in enumerate([(0, 0.3), (15, 0.3), (40, 0.3), (5, 0.01), (10, 2.0), (0, 0.0)]):
        m.keyframes.append(Keyframe(kf_id, empty, yawed(deg, x), np.zeros(0, np.int64)))
    got = m.keyframes_in_view(m.keyframes[5].pose, exclude={5}, count=3, max_angle_deg=20.0, max_distance=0.5,
                              min_distance=0.03)
    assert got == [0, 1]
