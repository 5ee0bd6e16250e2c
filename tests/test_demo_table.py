"""The demo's table: compute and network time apart, speedup against the robot's own run."""

from __future__ import annotations

import pytest

from workloads.motion_planning.demo import Row, geometric_mean, table


def test_row_splits_network_from_compute_and_computes_speedup() -> None:
    row = Row("maze", edge_s=4.0, edge_solved=3, cloud_compute_s=1.5, cloud_round_trip_s=1.6, cloud_solved=3, runs=3)
    assert row.network_s == pytest.approx(0.1)
    assert row.speedup == pytest.approx(2.5)
    text = table([row], cloud_cores=16)
    assert "cloud 16 cores" in text.splitlines()[0]
    assert text.splitlines()[2].split() == ["maze", "4.00s", "1.50s", "0.100s", "1.60s", "2.50x", "3/3", "3/3"]


def test_geometric_mean_of_speedups() -> None:
    assert geometric_mean([2.0, 0.5, 1.0]) == pytest.approx(1.0)
    assert geometric_mean([]) == 0.0
