"""The demo's table: compute and network time apart, speedup against the robot's own run."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from fogiac.procs import cpu_seconds, poll
from workloads.motion_planning.demo import CoresUsed, Row, _runs_node, geometric_mean, table


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


def test_the_cloud_node_is_found_by_its_command_line_and_its_cores_counted() -> None:
    # python -c leaves the rest of argv alone: a busy process that looks like the node to /proc
    node = subprocess.Popen([sys.executable, "-c", "while True: pass", "-m", "workloads.motion_planning", "node"])
    try:
        assert poll(lambda: _runs_node(node.pid) or None, timeout=30, interval=0.05) is True
        assert not _runs_node(os.getpid())
        used = CoresUsed(lambda: [node.pid])
        with used.measure() as walls:
            start = cpu_seconds(node.pid)
            poll(lambda: cpu_seconds(node.pid) >= start + 0.05 or None, timeout=60, interval=0.05)
            walls.append(1.0)
        assert used.cpu_s > 0 and used.cores == used.cpu_s
    finally:
        node.kill()
        node.wait()
    assert CoresUsed(list).cores is None  # no process seen: unknown, not zero
