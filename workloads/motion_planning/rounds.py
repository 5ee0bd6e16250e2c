"""The divided search's rounds, run by the workers among themselves in shared memory.

Thread model: k worker processes, no coordinator between rounds. The parent sends each worker
the request once and waits for k reports. In round r every worker

1. claims tasks one at a time from the shared counter ``claims[r % 2]`` (worker 0 zeroed it at the
   start of round r - 1's successor, while nobody used it) and writes each task's outcome into its
   slot of ``records[r % 2]`` (a fixed-size row of doubles);
2. worker 0 alone then decides whether the search stops after this round (time up, or its parent
   gone) into ``stop[r % 2]``;
3. all wait at the barrier, then read every record of the round and apply the same merge
   (``divided.merge_round``) to their own copy of the trees, so the copies stay identical, and all
   see the same joining task, if any, and the same stop decision.

Slots and counters alternate by the round's parity: the ones of round r are next written in round
r + 2, which no worker starts before every worker has passed round r + 1's barrier, so after
reading round r's. A worker that dies breaks the barrier (after ``BARRIER_TIMEOUT_S`` at worst):
the others give up the request, the pool replaces the dead one and resets the barrier.

What stays serial is the merge (every worker does the same one) and the barrier's latency; waiting
for the last worker's last task is imbalance. :class:`Division` puts figures on both.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from workloads.motion_planning.divided import MAX_CHAIN, TreeWorker, merge_round
from workloads.motion_planning.problem import Pose

BARRIER_TIMEOUT_S = 30.0
_HEAD = 8  # tree, near, has new, y, joined, goes on, chain length, used
RECORD = _HEAD + 7 + 7 * MAX_CHAIN


@dataclass
class Sync:
    """The shared objects of one pool's divided searches (made once, handed to every worker at start)."""

    claims: list[Any]  # two multiprocessing Values ("i"), with their locks
    stop: Any  # RawArray("b", 2)
    records: Any  # RawArray("d", 2 * max_tasks * RECORD)
    barrier: Any
    max_tasks: int

    @classmethod
    def create(cls, ctx: Any, *, workers: int, batch: int) -> Sync:
        max_tasks = 2 * batch  # a round's samples plus at most as many connects going on
        return cls([ctx.Value("i", 0), ctx.Value("i", 0)], ctx.RawArray("b", 2),
                   ctx.RawArray("d", 2 * max_tasks * RECORD), ctx.Barrier(workers), max_tasks)

    def claim(self, parity: int) -> int:
        counter = self.claims[parity]
        with counter.get_lock():
            counter.value += 1
            return int(counter.value) - 1


@dataclass(frozen=True)
class Division:
    """How a divided search's work fell on the workers, and how much of its time was serial."""

    checks: tuple[int, ...]  # collision checks per worker
    samples: tuple[int, ...]  # samples extended per worker
    busy_s: tuple[float, ...]  # seconds each worker spent on its tasks
    rounds: int
    wall_s: float  # the search's wall time, request sent to the last report in
    serial_s: float  # no worker on a task: merging, the barrier, the request and reports
    imbalance_s: float  # summed over rounds: the busiest worker's time on tasks over the average's

    @property
    def serial_share(self) -> float:
        return self.serial_s / self.wall_s if self.wall_s > 0 else 0.0

    def projected_speedup(self, cores: int) -> float:
        """Amdahl's law from this run's figures: the serial time (and the imbalance, counted as serial)
        stays, the tasks' work divides by ``cores``. A projection, not a measurement."""
        serial, work = self.serial_s + self.imbalance_s, sum(self.busy_s)
        return (serial + work) / (serial + work / cores) if serial + work > 0 else 1.0

    @classmethod
    def from_reports(cls, reports: list[dict[str, Any]], wall_s: float) -> Division:
        busy = np.array([r["round_busy_s"] for r in reports])  # workers x rounds
        rounds = busy.shape[1] if busy.ndim == 2 else 0
        peak = float(busy.max(axis=0).sum()) if rounds else 0.0
        imbalance = peak - float(busy.mean(axis=0).sum()) if rounds else 0.0
        return cls(tuple(r["checks"] for r in reports), tuple(r["samples"] for r in reports),
                   tuple(float(sum(r["round_busy_s"])) for r in reports), rounds, wall_s, max(0.0, wall_s - peak),
                   imbalance)

    def as_dict(self) -> dict[str, Any]:
        return {"checks": list(self.checks), "samples": list(self.samples), "busy_s": list(self.busy_s),
                "rounds": self.rounds, "wall_s": self.wall_s, "serial_s": self.serial_s,
                "imbalance_s": self.imbalance_s, "serial_share": self.serial_share}


def run_rounds(worker: TreeWorker, sync: Sync, *, index: int, start: Pose, goal: Pose, resolution: float,
               seed: int, batch: int, time_limit: float, cancelled: Callable[[], bool]) -> dict[str, Any]:
    """One worker's whole part of a divided search; worker 0's report carries the path."""
    deadline = time.perf_counter() + time_limit
    worker.checker.checks = 0
    status = worker.begin(start, goal, resolution=resolution, seed=seed, batch=batch)
    # the endpoints' and the straight move's checks, the same in every worker: kept apart from the shared work
    report: dict[str, Any] = {"round_busy_s": [], "samples": 0, "setup_checks": worker.checker.checks}
    worker.checker.checks = 0
    if status is not None:
        path = [start, goal] if status == "straight" else None
        return _report(report, worker, path, status)
    trees = worker.trees
    assert trees is not None
    pending: list[tuple[int, int, int]] = []
    records = np.frombuffer(sync.records, dtype=float)  # a view: no copy either way
    number = 0
    while True:
        parity = number % 2
        began = time.perf_counter()
        if index == 0:
            sync.claims[1 - parity].value = 0
        samples = worker.samples(number)
        tasks = len(pending) + batch
        while (i := sync.claim(parity)) < tasks:
            result = worker.task(i, number, pending, samples)
            report["samples"] += i >= len(pending)
            _write(records, (parity * sync.max_tasks + i) * RECORD, result)
        report["round_busy_s"].append(time.perf_counter() - began)
        if index == 0:
            sync.stop[parity] = time.perf_counter() >= deadline or cancelled()
        try:
            sync.barrier.wait(BARRIER_TIMEOUT_S)
        except threading.BrokenBarrierError:
            return _report(report, worker, None, "a worker died during the request")
        results = [_read(records, (parity * sync.max_tasks + i) * RECORD, i) for i in range(tasks)]
        _, pending, path = merge_round(trees, results)
        pending = pending[:batch]  # the oldest go on; the slots hold a round's samples plus as many
        number += 1
        if path is not None:
            return _report(report, worker, path, "first path")
        if sync.stop[parity]:
            return _report(report, worker, None, "timeout")


def _report(report: dict[str, Any], worker: TreeWorker, path: list[Pose] | None, status: str) -> dict[str, Any]:
    out = {**report, "checks": worker.checker.checks, "solved": path is not None, "status": status}
    if path is not None:
        out["path"] = [(p.x, p.y, p.z, p.qx, p.qy, p.qz, p.qw) for p in path]
    return out


def _write(buf: Any, at: int, result: tuple[Any, ...]) -> None:
    _, tree, near, new, y, chain, joined, goes_on = result
    row = np.zeros(RECORD)
    row[:_HEAD] = (tree, near, new is not None, y, joined, goes_on, len(chain), 1)
    if new is not None:
        row[_HEAD:_HEAD + 7] = new
    for j, pose in enumerate(chain):
        row[_HEAD + 7 * (j + 1):_HEAD + 7 * (j + 2)] = pose
    buf[at:at + RECORD] = row


def _read(buf: Any, at: int, i: int) -> tuple[Any, ...]:
    row = buf[at:at + RECORD]
    tree, near, has_new, y, joined, goes_on, count, _ = (int(v) for v in row[:_HEAD])
    new = row[_HEAD:_HEAD + 7].copy() if has_new else None
    chain = [row[_HEAD + 7 * (j + 1):_HEAD + 7 * (j + 2)].copy() for j in range(count)]
    return (i, tree, near, new, y, chain, bool(joined), bool(goes_on))
