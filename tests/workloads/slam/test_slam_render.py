"""The renderer's frames agree with its ground truth: depth seen from one pose predicts another's."""

from __future__ import annotations

import numpy as np
import pytest

from fogiac.errors import WorkloadError
from workloads.slam.camera import Intrinsics
from workloads.slam.geometry import inverse, transform
from workloads.slam.render import KINDS, Scene, render_sequence


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_depth_is_consistent_across_views(kind: str) -> None:
    k = Intrinsics.fr1().scaled(0.25)
    scene = Scene(k, seed=3)
    poses = KINDS[kind](300)  # the test sequences' spacing: frame 6 sees much of what frame 0 saw
    _, depth_a = scene.render(poses[0])
    _, depth_b = scene.render(poses[6])
    rng = np.random.default_rng(0)
    uv = np.column_stack([rng.integers(0, k.width, 400), rng.integers(0, k.height, 400)]).astype(np.float64)
    world = transform(poses[0], k.backproject(uv, depth_a[uv[:, 1].astype(int), uv[:, 0].astype(int)]))
    seen, z = k.project(transform(inverse(poses[6]), world))
    inside = k.inside(seen) & (z > 0)
    assert inside.mean() > 0.5
    measured = depth_b[seen[inside, 1].astype(int), seen[inside, 0].astype(int)]
    # Nearest-pixel lookup: most points land on the same surface, within a centimetre or two.
    assert np.median(np.abs(measured - z[inside])) < 0.02


def test_unknown_kind_lists_the_valid_ones(tmp_path) -> None:
    with pytest.raises(WorkloadError, match="unknown sequence kind 'spiral'; valid: bigloop, desk, forward, loop, turn, wall"):
        render_sequence(tmp_path, kind="spiral")
