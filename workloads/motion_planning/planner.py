"""Multi-core SE(3) planning: N OMPL planners race in N processes, the first path wins.

Python validity callbacks hold the GIL, so threads would not scale; processes do. Workers
come from a ``forkserver`` that has already imported OMPL, fcl and this module, so a solve
pays milliseconds, not seconds, to start them, and no fork copies a caller's threads (a
rospy node has several). The winner raises a shared flag that every other worker's
termination condition reads, simplifies its own path, proves it collision-free (repairing
what it cannot prove; see ``search.py``) and reports it; the parent then joins every worker
(killing any that outlive a grace period), so none is left behind. This is the cold path: each
solve builds its collision models anew. ``pool.WarmPlanner`` keeps workers and models alive.
"""

from __future__ import annotations

import dataclasses
import multiprocessing as mp
import os
import queue
import random
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from fogiac.errors import WorkloadError
from fogiac.procs import pid_alive
from workloads.motion_planning.problem import Pose, Problem, validity_resolution

if TYPE_CHECKING:  # rounds imports fcl-side code; a Solution only carries its record
    from workloads.motion_planning.rounds import Division
    from workloads.motion_planning.share import Phases

# name accepted on the CLI / in ROS params -> class in ompl.geometric
PLANNERS = {
    "rrtconnect": "RRTConnect",
    "rrt": "RRT",
    "kpiece": "KPIECE1",
    "bkpiece": "BKPIECE1",
    "lbkpiece": "LBKPIECE1",
    "prm": "PRM",
}
DEFAULT_PLANNER = "rrtconnect"
_JOIN_GRACE_S = 2.0
_PARENT_CHECK_EVERY = 2000


@dataclass(frozen=True)
class Solution:
    """What a solve produced; ``path`` poses carry quaternions (x, y, z, w), start to goal."""

    solved: bool
    status: str
    path: tuple[Pose, ...]
    cores: int
    solve_time_s: float  # wall clock from the call to a simplified path in hand
    plan_time_s: float  # the winning planner's own search time
    simplify_time_s: float
    winner: int | None  # index of the worker whose path won
    planner: str
    collision_checks: int = 0  # the winner's checks up to its first path: work, unlike time, ignores load
    resolution: float = 0.0  # world units a robot point moved at most between two checks while planning
    check_resolution: float = 0.0  # the path was proven free in pieces no shorter than this
    repairs: int = 0  # segments re-planned because they could not be proven free
    pieces: int = 1  # how many workers simplified and proved a piece of the path (share mode)
    cpu_s: float = 0.0  # CPU seconds on the critical path (winner's search + its, or the slowest piece's, finish)
    division: Division | None = None  # the divided search's work per worker and serial time (mode divide)
    phases: Phases | None = None  # the whole solve's split by phase, serial CPU included (mode divide)

    def as_dict(self) -> dict[str, Any]:
        return {
            "solved": self.solved, "status": self.status, "cores": self.cores,
            "solve_time_s": self.solve_time_s, "plan_time_s": self.plan_time_s,
            "simplify_time_s": self.simplify_time_s, "winner": self.winner, "planner": self.planner,
            "collision_checks": self.collision_checks, "resolution": self.resolution,
            "check_resolution": self.check_resolution, "repairs": self.repairs,
            "pieces": self.pieces, "cpu_s": self.cpu_s,
            "division": self.division.as_dict() if self.division is not None else None,
            "phases": self.phases.as_dict() if self.phases is not None else None,
            "path": [p.as_dict() for p in self.path],
        }


_CONTEXT: Any = None


def worker_context() -> Any:
    """The forkserver context, preloading the heavy imports once per calling process."""
    global _CONTEXT
    if _CONTEXT is None:
        _CONTEXT = mp.get_context("forkserver")
        _CONTEXT.set_forkserver_preload(["workloads.motion_planning.search"])
    return _CONTEXT


_WARM = False


def warm_up() -> None:
    """Start the fork server and let it finish its imports, so no timed solve pays for them."""
    global _WARM
    if not _WARM:
        probe = worker_context().Process(target=_noop, name="mp-planner-warm-up", daemon=True)
        probe.start()
        probe.join()
        probe.close()
        _WARM = True


def _noop() -> None:
    pass


def check_request(problem: Problem, *, cores: int | None, time_limit: float | None, planner: str,
                  resolution: float | None) -> tuple[int, float, float]:
    """(cores, time limit, resolution) a request asks for, defaults filled in; bad values raise."""
    if planner not in PLANNERS:
        raise WorkloadError(f"unknown planner {planner!r}; valid: {', '.join(sorted(PLANNERS))}")
    n = cores if cores is not None else (os.cpu_count() or 1)
    if n < 1:
        raise WorkloadError(f"cores must be at least 1, got {n}")
    limit = problem.time_limit if time_limit is None else time_limit
    if limit <= 0:
        raise WorkloadError(f"time limit must be positive, got {limit:g}")
    res = validity_resolution(problem) if resolution is None else resolution
    if not res > 0:
        raise WorkloadError(f"resolution must be positive, got {res:g}")
    return n, limit, res


def solution_from(report: dict[str, Any] | None, statuses: list[str], *, cores: int, elapsed: float,
                  planner: str) -> Solution:
    """A Solution from the winning worker's report (None: nobody won; statuses say why)."""
    if report is None:
        return Solution(False, statuses[0] if statuses else "no worker ran", (), cores, elapsed, 0.0, 0.0, None,
                        planner)
    path = tuple(Pose(*p) for p in report.get("path", ()))
    return Solution(report["solved"], report["status"], path, cores, elapsed, report["plan_time_s"],
                    report.get("simplify_time_s", 0.0), report["index"], planner, report["checks"],
                    report.get("resolution", 0.0), report.get("check_resolution", 0.0), report.get("repairs", 0),
                    report.get("pieces", 1), report.get("cpu_s", 0.0), report.get("division"),
                    report.get("phases"))


def solve(problem: Problem, *, cores: int | None = None, time_limit: float | None = None,
          seed: int | None = None, planner: str = DEFAULT_PLANNER, simplify_time: float = 0.5,
          resolution: float | None = None, mode: str = "divide") -> Solution:
    """Plan from ``problem.start`` to ``problem.goal`` on ``cores`` worker processes, started cold.

    ``mode="divide"`` (the default) splits one search between them (``divided.py``), then shares
    the finish; ``"race"`` races ``cores`` OMPL planners (``planner``), the first path winning;
    ``"share"`` races, then shares the finish (``share.py``). ``resolution`` (world units)
    overrides the problem's validity resolution for this request.
    """
    n, limit, res = check_request(problem, cores=cores, time_limit=time_limit, planner=planner,
                                  resolution=resolution)
    base_seed = seed if seed is not None else random.SystemRandom().randrange(2**31)
    warm_up()  # a one-off per calling process, kept out of solve_time_s
    if mode != "race":
        return _solve_pooled(problem, cores=n, time_limit=limit, seed=base_seed, planner=planner,
                             simplify_time=simplify_time, resolution=res, mode=mode)
    ctx = worker_context()
    flag = ctx.RawValue("b", 0)
    results = ctx.Queue()
    t0 = time.perf_counter()
    workers = [
        ctx.Process(target=_worker, name=f"mp-planner-{i}", daemon=True,
                    args=(problem, planner, ompl_seed(base_seed + i), res, limit, simplify_time, flag, results, i,
                          os.getpid()))
        for i in range(n)
    ]
    winner: dict[str, Any] | None = None
    statuses: list[str] = []
    started: list[Any] = []
    try:
        for w in workers:
            w.start()
            started.append(w)
        deadline = t0 + limit + simplify_time + 30.0  # generous: start-up and simplification
        while winner is None and len(statuses) < n:
            msg = _next_message(results, started, deadline)
            if msg is None:
                statuses.append("a worker died or hung without reporting")
                break
            if "plan_time_s" in msg:  # it found a path first: the answer, proven or not
                winner = msg
            else:
                statuses.append(msg["status"])
        elapsed = time.perf_counter() - t0
    finally:
        flag.value = 1
        _reap(started, results)
    return solution_from(winner, statuses, cores=n, elapsed=elapsed, planner=planner)


def _solve_pooled(problem: Problem, *, cores: int, time_limit: float, seed: int, planner: str,
                  simplify_time: float, resolution: float, mode: str) -> Solution:
    """A warm planner started for this one request: its start-up counts in ``solve_time_s``, as a race's does."""
    from workloads.motion_planning.pool import WarmPlanner  # noqa: PLC0415 (pool imports this module)

    t0 = time.perf_counter()
    with WarmPlanner({problem.name: problem}, workers=cores, planner=planner, seed=seed, simplify_time=simplify_time,
                     mode=mode) as warm:
        solution = warm.solve(problem.name, time_limit=time_limit, resolution=resolution, seed=seed)
        return dataclasses.replace(solution, solve_time_s=time.perf_counter() - t0)


def ompl_seed(seed: int) -> int:
    """Any int to OMPL's seed range: OMPL ignores a seed of 0 and takes only unsigned 32-bit ones."""
    return seed % (2**31 - 1) + 1


def _next_message(results: Any, workers: list[Any], deadline: float) -> dict[str, Any] | None:
    """The next worker report; None once every worker is gone (or the deadline passed) without one."""
    while time.perf_counter() < deadline:
        try:
            return results.get(timeout=0.05)
        except queue.Empty:
            if not any(w.is_alive() for w in workers):
                try:  # a worker may have exited right after reporting
                    return results.get(timeout=0.5)
                except queue.Empty:
                    return None
    return None


def _reap(workers: list[Any], results: Any) -> None:
    """Join every worker, draining the queue so none blocks on a full pipe; kill stragglers."""
    end = time.perf_counter() + _JOIN_GRACE_S
    for w in workers:
        while w.is_alive() and time.perf_counter() < end:
            _drain(results)
            w.join(timeout=0.05)
    for w in workers:
        if w.is_alive():
            w.kill()
        w.join()
        w.close()
    _drain(results)
    results.close()
    results.join_thread()


def _drain(results: Any) -> None:
    try:
        while True:
            results.get_nowait()
    except (queue.Empty, OSError, ValueError):
        pass


def _worker(problem: Problem, planner: str, seed: int, resolution: float, time_limit: float,
            simplify_time: float, flag: Any, results: Any, index: int, parent_pid: int) -> None:
    """One racing planner; runs in its own process and reports one message."""
    try:
        from workloads.motion_planning.search import Search, seed_process  # noqa: PLC0415 (OMPL: workers only)

        seed_process(seed)
        report = Search(problem).run(
            problem.start, problem.goal, planner=PLANNERS[planner], resolution=resolution,
            time_limit=time_limit, simplify_time=simplify_time, cancelled=cancel_test(flag, parent_pid),
            on_first_path=raise_on_first_path(flag))
        results.put({**report, "index": index})
    except Exception as err:  # report, do not hang the parent
        results.put({"solved": False, "status": f"worker error: {err}", "index": index})


def cancel_test(flag: Any, parent_pid: int) -> Callable[[], bool]:
    """A termination test for OMPL: another worker won, or the parent is gone (orphaned: give up)."""
    calls = [0]

    def cancelled() -> bool:
        if flag.value:
            return True
        calls[0] += 1
        return calls[0] % _PARENT_CHECK_EVERY == 0 and not pid_alive(parent_pid)

    return cancelled


def raise_on_first_path(flag: Any) -> Callable[[], None]:
    def first_path() -> None:
        flag.value = 1  # stop the others now; simplifying and proving the path is the winner's alone

    return first_path
