"""The divided search's rounds, run by the workers among themselves in shared memory.

Thread model: k worker processes, no coordinator between rounds. The parent sends each worker
the request once and reads k reports. Round r lives in slot ``r % SLOTS`` of the shared arrays,
and its tasks see the trees as merged through round r - LAG - 1 (``TreeWorker.task``'s view), so
no worker waits for round r - 1's last tasks before it starts on round r:

1. a worker entering round r waits until every worker has merged round r - SLOTS (so the slot is
   free), then claims tasks one at a time from the slot's counter (the first to claim in round r
   clears the slot, under the slot's lock) and writes each task's outcome into the task's record,
   then marks it done;
2. when the claims run out it turns to round r - LAG: its tasks were all claimed before round
   r's first, so the other workers have had a whole round's claims to finish them in and it
   rarely waits. One still not done after ``STEAL_AFTER_S`` (its worker is likely parked by the
   kernel on a busy machine) it runs itself: a task's outcome depends only on the trees, the
   round's view of them and the seed, so both copies write the same bytes;
3. it reads every record of round r - LAG and applies the same merge (``divided.merge_round``)
   to its own copy of the trees, so all copies stay identical and all see the same joining task;
   then it claims round r + 1's tasks.

So the search depends on the seed alone (1 and k workers grow the same trees), a worker can be up
to SLOTS - 1 rounds ahead of another, a parked worker delays the others by at most the steal
time, and the price of the lag is LAG rounds of tasks that see slightly older trees, and LAG
rounds run after the one that joins the trees (the path is that round's: the same for any k).
The search ends for everyone when one worker raises ``finished`` (a path merged, time up, parent
gone); the path is the same in any report that has it. What stays serial is drawing the samples
and the merge, which every worker does; waiting for a round's last tasks is imbalance.
:class:`Division` puts figures on both.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from workloads.motion_planning.divided import MAX_CHAIN, TreeWorker, merge_round
from workloads.motion_planning.problem import Pose

SLOTS = 4  # rounds in flight: a worker may run SLOTS - 1 rounds ahead of the slowest
LAG = 1  # round r's tasks see the trees as merged through round r - LAG - 1 (see the module doc)
STEAL_AFTER_S = 0.002  # a task not done this long after the claims ran out is run again by a waiting worker
SPIN_S, NAP_S = 0.0002, 0.0002
_HEAD = 8  # tree, near, has new, y, joined, goes on, chain length, spare
RECORD = _HEAD + 7 + 7 * MAX_CHAIN


@dataclass
class Sync:
    """The shared objects of one pool's divided searches (made once, handed to every worker at start)."""

    locks: list[Any]  # one per slot: guards its round number and claim counter
    slot_round: Any  # RawArray("i", SLOTS): which round a slot holds
    claims: Any  # RawArray("i", SLOTS): the slot's next unclaimed task
    done: Any  # RawArray("b", SLOTS * max_tasks)
    records: Any  # RawArray("d", SLOTS * max_tasks * RECORD)
    reached: Any  # RawArray("i", workers): rounds each worker has merged
    finished: Any  # RawValue("i")
    max_tasks: int
    finish_lock: Any = None  # guards finish_next
    finish_next: Any = None  # RawValue("i"): the divided finish's next unclaimed piece

    @classmethod
    def create(cls, ctx: Any, *, workers: int, batch: int) -> Sync:
        max_tasks = 2 * batch  # a round's samples plus at most as many connects going on
        return cls([ctx.Lock() for _ in range(SLOTS)], ctx.RawArray("i", SLOTS), ctx.RawArray("i", SLOTS),
                   ctx.RawArray("b", SLOTS * max_tasks), ctx.RawArray("d", SLOTS * max_tasks * RECORD),
                   ctx.RawArray("i", workers), ctx.RawValue("i", 0), max_tasks, ctx.Lock(), ctx.RawValue("i", 0))

    def claim_piece(self) -> int:
        with self.finish_lock:
            i = int(self.finish_next.value)
            self.finish_next.value = i + 1
            return i

    def reset(self) -> None:
        """Before a request, while no worker runs one."""
        for s in range(SLOTS):
            self.slot_round[s] = -1
            self.claims[s] = 0
        for w in range(len(self.reached)):
            self.reached[w] = 0
        self.finished.value = 0
        self.finish_next.value = 0

    def claim(self, number: int, tasks: int) -> int:
        slot = number % SLOTS
        with self.locks[slot]:
            if self.slot_round[slot] != number:  # the first claim of the round clears the slot
                self.slot_round[slot] = number
                self.claims[slot] = 0
                start = slot * self.max_tasks
                self.done[start:start + tasks] = bytes(tasks)
            i = int(self.claims[slot])
            self.claims[slot] = i + 1
            return i


@dataclass(frozen=True)
class Division:
    """How a divided search's work fell on the workers, and how much of its time was serial."""

    checks: tuple[int, ...]  # collision checks per worker (tasks run twice included)
    samples: tuple[int, ...]  # samples extended per worker
    busy_s: tuple[float, ...]  # seconds each worker spent on tasks
    rounds: int
    wall_s: float  # the search's wall time, request sent to the last report in
    serial_s: float  # not on tasks nor waiting for them: merging, the request and reports
    imbalance_s: float  # waiting for a round's last tasks, averaged over the workers
    stolen_checks: tuple[int, ...] = ()  # checks in tasks a worker ran again for a parked one
    cpu_s: tuple[float, ...] = ()  # CPU seconds each worker's process used in the search (waiting included)
    serial_cpu_s: tuple[float, ...] = ()  # of which drawing the rounds' samples and merging them (every worker)

    @property
    def serial_share(self) -> float:
        return self.serial_s / self.wall_s if self.wall_s > 0 else 0.0

    @property
    def serial_cpu_share(self) -> float:
        """The workers' CPU seconds in the serial part (the samples and the merge, which every worker does)
        over their CPU seconds in the search: what other jobs' load does not stretch, unlike the wall."""
        total = sum(self.cpu_s)
        return sum(self.serial_cpu_s) / total if total > 0 else 0.0

    def projected_speedup(self, cores: int) -> float:
        """Amdahl's law from this run's figures: the serial time (and the imbalance, counted as serial)
        stays, the tasks' work divides by ``cores``. A projection, not a measurement."""
        serial, work = self.serial_s + self.imbalance_s, sum(self.busy_s) - self._stolen_s()
        return (serial + work) / (serial + work / cores) if serial + work > 0 else 1.0

    def projected_speedup_cpu(self, cores: int) -> float:
        """The same law on CPU seconds, which other jobs' load does not stretch: one worker's serial CPU
        (samples and merge, done by every worker) stays, the rest of the workers' CPU (less the tasks run
        twice) divides by ``cores``. Leaves out waiting, which the wall-time projection counts."""
        if not self.cpu_s:
            return 1.0
        serial = sum(self.serial_cpu_s) / len(self.cpu_s)
        total = sum(self.checks)
        work = (sum(self.cpu_s) - sum(self.serial_cpu_s)) * (1 - sum(self.stolen_checks) / total if total else 1)
        return (serial + work) / (serial + work / cores) if serial + work > 0 else 1.0

    def _stolen_s(self) -> float:
        total = sum(self.checks)
        return sum(self.busy_s) * sum(self.stolen_checks) / total if total else 0.0

    @classmethod
    def from_reports(cls, reports: list[dict[str, Any]], wall_s: float) -> Division:
        k = len(reports)
        busy = [float(r["busy_s"]) for r in reports]
        waiting = sum(float(r["wait_s"]) for r in reports) / k
        serial = max(0.0, wall_s - sum(busy) / k - waiting)
        return cls(tuple(r["checks"] for r in reports), tuple(r["samples"] for r in reports), tuple(busy),
                   max(r["rounds"] for r in reports), wall_s, serial, waiting,
                   tuple(r["stolen_checks"] for r in reports), tuple(r["cpu_s"] for r in reports),
                   tuple(r.get("serial_cpu_s", 0.0) for r in reports))

    def as_dict(self) -> dict[str, Any]:
        return {"checks": list(self.checks), "samples": list(self.samples), "busy_s": list(self.busy_s),
                "rounds": self.rounds, "wall_s": self.wall_s, "serial_s": self.serial_s,
                "imbalance_s": self.imbalance_s, "serial_share": self.serial_share,
                "stolen_checks": list(self.stolen_checks), "cpu_s": list(self.cpu_s),
                "serial_cpu_s": list(self.serial_cpu_s), "serial_cpu_share": self.serial_cpu_share}


def worker_step(op: str, request: dict[str, Any], trees: TreeWorker, search: Any, sync: Sync, index: int,
                cancelled: Callable[[], bool]) -> dict[str, Any]:
    """A pool worker's part of a divided request: its share of the search's rounds, or lifting the found
    path clear of the walls (``search``: the worker's ``search.Search`` of the problem)."""
    if op == "search":
        return run_rounds(trees, sync, index=index, start=request["start"], goal=request["goal"],
                          resolution=request["resolution"], seed=request["seed"], batch=request["batch"],
                          time_limit=request["time_limit"], cancelled=cancelled)
    if op == "finish":
        return finish_pieces(request, search, sync)
    cpu = time.process_time()
    path = search.lift([Pose(*p) for p in request["path"]], request["resolution"])
    return {"path": [(p.x, p.y, p.z, p.qx, p.qy, p.qz, p.qw) for p in path], "cpu_s": time.process_time() - cpu}


def finish_pieces(request: dict[str, Any], search: Any, sync: Sync) -> dict[str, Any]:
    """A worker's part of the divided finish: pieces of the found path claimed one at a time from the shared
    counter until none is left, each lifted (its ends against the path as found, so the two workers of a
    joint lift it alike), simplified and proven; a worker that drew long pieces claims fewer, so no worker
    waits long for another's last piece, and none lifts the whole path while the others wait."""
    cpu, began = time.process_time(), time.perf_counter()
    path, cuts, res = [Pose(*p) for p in request["path"]], request["cuts"], request["resolution"]
    deadline = time.perf_counter() + request["time_limit"]
    pieces: dict[int, dict[str, Any]] = {}
    while (i := sync.claim_piece()) < len(cuts) - 1:
        a, b = cuts[i], cuts[i + 1]
        piece = [search.lift_at(path, a, res), *path[a + 1:b], search.lift_at(path, b, res)]
        pieces[i] = search.finish(piece, planner=request["planner"], resolution=res,
                                  time_limit=max(1e-3, deadline - time.perf_counter()),
                                  simplify_time=request["simplify_times"][i], lift_first=True)
    return {"pieces": pieces, "claims": len(pieces), "cpu_s": time.process_time() - cpu,
            "wall_s": time.perf_counter() - began, "solved": True, "status": "finished"}


class _Stop(Exception):
    pass


def run_rounds(worker: TreeWorker, sync: Sync, *, index: int, start: Pose, goal: Pose, resolution: float,
               seed: int, batch: int, time_limit: float, cancelled: Callable[[], bool]) -> dict[str, Any]:
    """One worker's whole part of a divided search; every report that has a path has the same one."""
    deadline = time.perf_counter() + time_limit
    worker.checker.checks = 0
    status = worker.begin(start, goal, resolution=resolution, seed=seed, batch=batch)
    # the endpoints' and the straight move's checks, the same in every worker: kept apart from the shared work
    report: dict[str, Any] = {"busy_s": 0.0, "wait_s": 0.0, "samples": 0, "rounds": 0, "stolen_checks": 0,
                              "setup_checks": worker.checker.checks, "cpu_s": time.process_time(), "serial_cpu_s": 0.0}
    worker.checker.checks = 0
    if status is not None:
        return _report(report, worker, [start, goal] if status == "straight" else None, status)
    trees = worker.trees
    assert trees is not None
    records, done = np.frombuffer(sync.records, dtype=float), np.frombuffer(sync.done, dtype=np.int8)
    # per round in flight: the connects it goes on with, the tree sizes its tasks see, its samples
    pendings: dict[int, list[tuple[int, int, int]]] = {r: [] for r in range(LAG + 1)}
    views: dict[int, tuple[int, int]] = {r: (1, 1) for r in range(LAG + 1)}
    drawn: dict[int, np.ndarray] = {}

    def stop_now() -> bool:
        if sync.finished.value:
            return True
        if time.perf_counter() >= deadline or cancelled():
            sync.finished.value = 1
            return True
        return False

    def tasks_of(r: int) -> int:
        return len(pendings[r]) + batch

    def run(r: int, i: int) -> None:
        """Task i of round r: its outcome into its record, then marked done."""
        base = (r % SLOTS) * sync.max_tasks
        _write(records, (base + i) * RECORD, worker.task(i, r, pendings[r], drawn[r], views[r]))
        done[base + i] = 1

    number = 0  # the round whose tasks this worker claims next; it has merged rounds up to number - LAG - 1
    try:
        while True:
            waited = time.perf_counter()
            while min(sync.reached) < number - SLOTS + 1:  # the slot's last round not merged by all yet
                _idle(stop_now, waited)
            cpu = time.process_time()
            drawn[number] = worker.samples(number)
            report["serial_cpu_s"] += time.process_time() - cpu
            began = time.perf_counter()
            report["wait_s"] += began - waited
            tasks = tasks_of(number)
            while (i := sync.claim(number, tasks)) < tasks:
                run(number, i)
                report["samples"] += i >= len(pendings[number])
                if sync.finished.value:
                    raise _Stop
            report["busy_s"] += time.perf_counter() - began
            number += 1
            merge = number - 1 - LAG  # its tasks have had LAG rounds' claims to finish in
            if merge < 0:
                continue
            base, tasks = (merge % SLOTS) * sync.max_tasks, tasks_of(merge)
            waited = time.perf_counter()
            while not done[base:base + tasks].all():  # its last tasks, in other workers' hands
                if time.perf_counter() - waited < STEAL_AFTER_S:
                    _idle(stop_now, waited)
                    continue
                i = int(np.argmin(done[base:base + tasks]))
                checks, ran = worker.checker.checks, time.perf_counter()
                run(merge, i)  # its claimer counts the sample
                report["stolen_checks"] += worker.checker.checks - checks
                report["busy_s"] += time.perf_counter() - ran
                waited -= time.perf_counter() - ran
            report["wait_s"] += time.perf_counter() - waited
            cpu = time.process_time()
            results = _read_round(records, base, tasks)
            _, pending, path = merge_round(trees, results)
            report["serial_cpu_s"] += time.process_time() - cpu
            # the round LAG + 1 on sees it; the oldest connects go on (a slot holds a batch plus as many)
            pendings[merge + LAG + 1] = pending[:batch]
            views[merge + LAG + 1] = (trees.size(0), trees.size(1))
            for old in (pendings, views, drawn):
                old.pop(merge, None)
            sync.reached[index] = merge + 1
            report["rounds"] = merge + 1
            if path is not None:
                sync.finished.value = 1
                return _report(report, worker, path, "first path")
            if stop_now():
                raise _Stop
    except _Stop:
        sync.reached[index] = 1 << 30  # never again a worker to wait for
        return _report(report, worker, None, "timeout")


def _idle(stop_now: Callable[[], bool], since: float) -> None:
    """Spin briefly (a task ends within ~0.1 ms as often as not), then sleep in short naps: on a busy
    machine a spinning waiter would take the CPU the worker it waits for needs."""
    if stop_now():
        raise _Stop
    if time.perf_counter() - since < SPIN_S:
        os.sched_yield()
    else:
        time.sleep(NAP_S)


def _report(report: dict[str, Any], worker: TreeWorker, path: list[Pose] | None, status: str) -> dict[str, Any]:
    out = {**report, "checks": worker.checker.checks, "solved": path is not None, "status": status,
           "cpu_s": time.process_time() - report["cpu_s"]}
    if path is not None:
        out["path"] = [(p.x, p.y, p.z, p.qx, p.qy, p.qz, p.qw) for p in path]
    return out


def _write(buf: np.ndarray, at: int, result: tuple[Any, ...]) -> None:
    _, tree, near, new, y, chain, joined, goes_on = result
    row = np.zeros(RECORD)
    row[:_HEAD] = (tree, near, new is not None, y, joined, goes_on, len(chain), 0)
    if new is not None:
        row[_HEAD:_HEAD + 7] = new
    for j, pose in enumerate(chain):
        row[_HEAD + 7 * (j + 1):_HEAD + 7 * (j + 2)] = pose
    buf[at:at + RECORD] = row


def _read_round(buf: np.ndarray, base: int, tasks: int) -> list[tuple[Any, ...]]:
    """The round's records, in task order, as ``merge_round`` takes them."""
    rows = buf[base * RECORD:(base + tasks) * RECORD].reshape(tasks, RECORD)
    out: list[tuple[Any, ...]] = []
    for i, (tree, near, has_new, y, joined, goes_on, count, _) in enumerate(rows[:, :_HEAD].astype(np.int64).tolist()):
        new = rows[i, _HEAD:_HEAD + 7].copy() if has_new else None
        chain = list(rows[i, _HEAD + 7:_HEAD + 7 * (count + 1)].reshape(count, 7).copy()) if count else []
        out.append((i, tree, near, new, y, chain, bool(joined), bool(goes_on)))
    return out
