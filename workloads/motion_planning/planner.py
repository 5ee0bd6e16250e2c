"""Multi-core SE(3) planning: N OMPL planners race in N processes, the first path wins.

Python validity callbacks hold the GIL, so threads would not scale; processes do. Workers
come from a ``forkserver`` that has already imported OMPL, fcl and this module, so a solve
pays milliseconds, not seconds, to start them, and no fork copies a caller's threads (a
rospy node has several). The winner raises a shared flag that every other worker's
termination condition reads, simplifies its own path, and reports it; the parent then
joins every worker (killing any that outlive a grace period), so none is left behind.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import queue
import random
import time
from dataclasses import dataclass
from typing import Any

from fogiac.errors import WorkloadError
from fogiac.procs import pid_alive
from workloads.motion_planning.geometry import CollisionChecker
from workloads.motion_planning.problem import Pose, Problem

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

    def as_dict(self) -> dict[str, Any]:
        return {
            "solved": self.solved, "status": self.status, "cores": self.cores,
            "solve_time_s": self.solve_time_s, "plan_time_s": self.plan_time_s,
            "simplify_time_s": self.simplify_time_s, "winner": self.winner, "planner": self.planner,
            "collision_checks": self.collision_checks,
            "path": [p.as_dict() for p in self.path],
        }


_CONTEXT: Any = None


def _context() -> Any:
    """The forkserver context, preloading the heavy imports once per calling process."""
    global _CONTEXT
    if _CONTEXT is None:
        _CONTEXT = mp.get_context("forkserver")
        _CONTEXT.set_forkserver_preload(["workloads.motion_planning.planner"])
    return _CONTEXT


_WARM = False


def warm_up() -> None:
    """Start the fork server and let it finish its imports, so no timed solve pays for them."""
    global _WARM
    if not _WARM:
        probe = _context().Process(target=_noop, name="mp-planner-warm-up", daemon=True)
        probe.start()
        probe.join()
        probe.close()
        _WARM = True


def _noop() -> None:
    pass


def solve(problem: Problem, *, cores: int | None = None, time_limit: float | None = None,
          seed: int | None = None, planner: str = DEFAULT_PLANNER, simplify_time: float = 0.5) -> Solution:
    """Plan from ``problem.start`` to ``problem.goal`` with ``cores`` racing planners."""
    if planner not in PLANNERS:
        raise WorkloadError(f"unknown planner {planner!r}; valid: {', '.join(sorted(PLANNERS))}")
    n = cores if cores is not None else (os.cpu_count() or 1)
    if n < 1:
        raise WorkloadError(f"cores must be at least 1, got {n}")
    limit = problem.time_limit if time_limit is None else time_limit
    if limit <= 0:
        raise WorkloadError(f"time limit must be positive, got {limit:g}")
    base_seed = seed if seed is not None else random.SystemRandom().randrange(2**31)
    warm_up()  # a one-off per calling process, kept out of solve_time_s
    ctx = _context()
    flag = ctx.RawValue("b", 0)
    results = ctx.Queue()
    t0 = time.perf_counter()
    workers = [
        ctx.Process(target=_worker, name=f"mp-planner-{i}", daemon=True,
                    args=(problem, planner, _ompl_seed(base_seed + i), limit, simplify_time, flag, results, i,
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
            if msg["solved"]:
                winner = msg
            else:
                statuses.append(msg["status"])
        elapsed = time.perf_counter() - t0
    finally:
        flag.value = 1
        _reap(started, results)
    if winner is None:
        return Solution(False, statuses[0] if statuses else "no worker ran", (), n, elapsed, 0.0, 0.0, None, planner)
    path = tuple(Pose(*p) for p in winner["path"])
    return Solution(True, winner["status"], path, n, elapsed, winner["plan_time_s"], winner["simplify_time_s"],
                    winner["index"], planner, winner["checks"])


def _ompl_seed(seed: int) -> int:
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


def _worker(problem: Problem, planner: str, seed: int, time_limit: float, simplify_time: float,
            flag: Any, results: Any, index: int, parent_pid: int) -> None:
    """One racing planner; runs in its own process and reports one message."""
    try:
        results.put(_plan_one(problem, planner, seed, time_limit, simplify_time, flag, index, parent_pid))
    except Exception as err:  # report, do not hang the parent
        results.put({"solved": False, "status": f"worker error: {err}", "index": index})


def _plan_one(problem: Problem, planner: str, seed: int, time_limit: float, simplify_time: float,
              flag: Any, index: int, parent_pid: int) -> dict[str, Any]:
    # ompl loads in each racing worker only: importing this module (the node, `solve --help`) stays light.
    import ompl.base as ob  # noqa: PLC0415
    import ompl.geometric as og  # noqa: PLC0415
    import ompl.util as ou  # noqa: PLC0415

    ou.setLogLevel(ou.LOG_ERROR)
    ou.RNG.setSeed(seed)
    space = ob.SE3StateSpace()
    bounds = ob.RealVectorBounds(3)
    for i in range(3):
        bounds.setLow(i, problem.bounds_min[i])
        bounds.setHigh(i, problem.bounds_max[i])
    space.setBounds(bounds)
    space.setLongestValidSegmentFraction(problem.segment_fraction)
    setup = og.SimpleSetup(space)
    checker = CollisionChecker(problem)

    def valid(state: Any) -> bool:
        rot = state.rotation()
        return checker.is_free((state.getX(), state.getY(), state.getZ()), (rot.w, rot.x, rot.y, rot.z))

    setup.setStateValidityChecker(valid)
    start, goal = space.allocState(), space.allocState()
    for state, pose in ((start, problem.start), (goal, problem.goal)):
        state.setXYZ(pose.x, pose.y, pose.z)
        rot = state.rotation()
        rot.w, rot.x, rot.y, rot.z = (float(v) for v in pose.quaternion())
    setup.setStartAndGoalStates(start, goal)
    setup.setPlanner(getattr(og, PLANNERS[planner])(setup.getSpaceInformation()))
    calls = [0]

    def cancelled() -> bool:
        if flag.value:
            return True
        calls[0] += 1
        return calls[0] % _PARENT_CHECK_EVERY == 0 and not pid_alive(parent_pid)  # orphaned: give up

    ptc = ob.plannerOrTerminationCondition(ob.timedPlannerTerminationCondition(time_limit),
                                           ob.PlannerTerminationCondition(cancelled))
    status = str(setup.solve(ptc))
    if flag.value or not setup.haveExactSolutionPath():
        return {"solved": False, "status": "cancelled" if flag.value else status.lower(), "index": index}
    flag.value = 1  # stop the others now; simplification is ours alone
    plan_time, checks = setup.getLastPlanComputationTime(), checker.checks
    setup.simplifySolution(simplify_time)
    states = setup.getSolutionPath().getStates()
    path = [(s.getX(), s.getY(), s.getZ(), s.rotation().x, s.rotation().y, s.rotation().z, s.rotation().w)
            for s in states]
    return {"solved": True, "status": status.lower(), "index": index, "path": path,
            "plan_time_s": plan_time, "simplify_time_s": setup.getLastSimplificationTime(), "checks": checks}



