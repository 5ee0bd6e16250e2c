"""Tracking's search for descriptor candidates near each projected map point, against brute force."""

from __future__ import annotations

import numpy as np
import pytest

from workloads.slam.tracking import near_pairs


@pytest.mark.parametrize("radius", [5.0, 12.0, 36.0])
def test_near_pairs_finds_exactly_the_pairs_within_the_radius(radius: float) -> None:
    rng = np.random.default_rng(int(radius))
    for _ in range(40):
        # Features may sit on the image border and points project up to a radius outside it.
        features = rng.uniform(-radius, 640 + radius, (int(rng.integers(0, 400)), 2)).astype(np.float32)
        points = rng.uniform(-3 * radius, 640 + 3 * radius, (int(rng.integers(0, 400)), 2))
        feat, point = near_pairs(features, points, radius)
        found = set(zip(feat.tolist(), point.tolist(), strict=True))
        assert len(found) == len(feat)  # no pair twice
        squared = ((features[:, None, :] - points[None, :, :]) ** 2).sum(axis=-1)
        assert found == {(int(i), int(j)) for i, j in zip(*np.nonzero(squared < radius * radius), strict=True)}
