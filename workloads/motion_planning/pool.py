"""The warm planner: worker processes that outlive requests, with every known problem loaded once.

A cold :func:`planner.solve` starts its workers and builds their OMPL spaces and fcl models on
every call; a ROS node answering request after request would pay that each time. Here each
worker builds a :class:`search.Search` per known problem when it starts and then serves
requests (problem name, start, goal, limits) over its own pipe until it is closed:

- **one request at a time; a second waits its turn.** ``solve`` holds a lock for the whole
  race, so a request that arrives during another queues behind it (a robot re-sending would
  otherwise have to handle refusals; the node's subscriber queue bounds how many can wait).
- **every worker races every request**; the first to find a path raises the shared flag, the
  others stop within one planner iteration and report, so the next request starts clean.
- **a dead worker is replaced** before the next request (its problems loaded again); a worker
  that dies during a race counts as a loser of that race.
- a warm worker is seeded when it starts (``seed + index``), so runs repeat as a sequence; a
  request that names its own ``seed`` is repeatable alone: worker i draws from ``seed + i``
  whatever it did before, so one worker's search is the same on a 1-worker planner and as
  worker 0 of a larger one (the demo compares the robot and the cloud on the same draws).
- ``mode="divide"`` (the default) divides the search itself: every worker grows the same two trees,
  a share of each round's samples apiece (``divided.py``), then the path is finished in pieces as
  in ``share``. The search depends on the request's seed alone, not on the number of workers.
- ``mode="share"`` shares the work after the race: the first path is cut into a
  piece per worker and every worker simplifies and proves its piece (``share.py``); when a piece
  cannot be proven, one worker finishes the whole path in the time left (:attr:`refinished`);
  ``mode="race"`` leaves that to the winner alone. With one worker the two are the same.
"""

from __future__ import annotations

import os
import random
import threading
import time
from collections.abc import Mapping
from multiprocessing.connection import Connection, wait
from typing import Any

from fogiac.errors import WorkloadError
from fogiac.procs import pid_alive
from workloads.motion_planning.divided import TreeWorker, batch_size
from workloads.motion_planning.planner import (
    DEFAULT_PLANNER,
    PLANNERS,
    Solution,
    cancel_test,
    check_request,
    ompl_seed,
    raise_on_first_path,
    solution_from,
    worker_context,
)
from workloads.motion_planning.problem import Pose, Problem
from workloads.motion_planning.rounds import Division, Sync, worker_step
from workloads.motion_planning.share import (
    DEFAULT_MODE,
    MODES,
    Phases,
    cut_indices,
    join_reports,
    simplify_shares,
    split_path,
)

_READY_TIMEOUT_S = 120.0
_STOP_GRACE_S = 2.0
_IDLE_POLL_S = 1.0
_DIED = "a worker died during the request"
FINISH_PIECES_PER_WORKER = 3  # the divided finish's pieces: enough that claiming evens the work out, few enough
# that the cut poses (kept in the answer: no shortcut passes them) cost the path little


class WarmPlanner:
    """``workers`` long-lived planner processes racing on each request; close() (or ``with``) ends them."""

    def __init__(self, problems: Mapping[str, Problem], *, workers: int | None = None,
                 planner: str = DEFAULT_PLANNER, seed: int | None = None, simplify_time: float = 0.5,
                 mode: str = DEFAULT_MODE) -> None:
        if not problems:
            raise WorkloadError("a warm planner needs at least one problem")
        if mode not in MODES:
            raise WorkloadError(f"unknown mode {mode!r}; valid: {', '.join(MODES)}")
        self.mode = mode
        self.problems = dict(problems)
        any_problem = next(iter(self.problems.values()))
        self.workers, _, _ = check_request(any_problem, cores=workers, time_limit=None, planner=planner,
                                           resolution=None)
        self.planner, self.simplify_time = planner, simplify_time
        self.planner_class = PLANNERS[planner]
        self._seed = seed if seed is not None else random.SystemRandom().randrange(2**31)
        self._ctx = worker_context()
        self._flag = self._ctx.RawValue("b", 0)
        self._sync = Sync.create(self._ctx, workers=self.workers, batch=batch_size(self.workers))
        self._lock = threading.Lock()
        self._procs: list[Any] = [None] * self.workers
        self._conns: list[Connection | None] = [None] * self.workers
        self._request_id = 0
        self.replaced = 0  # workers started again after dying
        self.refinished = 0  # shared requests whose pieces failed, finished whole by one worker
        try:
            for i in range(self.workers):
                self._start(i)
            self._await_ready(range(self.workers))
        except BaseException:
            self.close()
            raise

    def __enter__(self) -> WarmPlanner:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def pids(self) -> list[int]:
        return [p.pid for p in self._procs if p is not None]

    def solve(self, name: str, *, start: Pose | None = None, goal: Pose | None = None,
              time_limit: float | None = None, resolution: float | None = None,
              simplify_time: float | None = None, seed: int | None = None) -> Solution:
        """Plan on a known problem (its own endpoints unless given); waits while another request runs.

        ``seed`` makes the request repeatable: worker i searches with ``seed + i`` (see the module doc).
        """
        if name not in self.problems:
            raise WorkloadError(f"unknown problem {name!r}; known: {', '.join(sorted(self.problems))}")
        problem = self.problems[name]
        _, limit, res = check_request(problem, cores=self.workers, time_limit=time_limit, planner=self.planner,
                                      resolution=resolution)
        with self._lock:
            self._replace_dead()
            parent_cpu = time.thread_time()  # this thread's work for the request: handing out, gathering, joining
            simplify = self.simplify_time if simplify_time is None else simplify_time
            sharing = self.mode == "share" and self.workers > 1
            request = {"name": name, "start": start or problem.start, "goal": goal or problem.goal,
                       "resolution": res, "time_limit": limit, "simplify_time": simplify, "finish": not sharing,
                       "seed": seed}
            t0 = time.perf_counter()
            if self.mode == "divide":
                winner, statuses = self._divide(request, seed=seed, deadline=t0 + limit + simplify + 30.0)
                if winner is None and statuses == [_DIED]:  # it needs every worker: replace the dead, once more
                    self._replace_dead()
                    winner, statuses = self._divide(request, seed=seed, deadline=t0 + limit + simplify + 30.0)
                sharing = self.workers > 1
            else:
                winner, statuses = self._race(request, deadline=t0 + limit + simplify + 30.0)
            if winner is not None and self.mode == "divide" and not sharing:
                winner = self._finish_whole(name, winner, request, left=t0 + limit - time.perf_counter(),
                                            deadline=t0 + limit + simplify + 30.0)
            elif winner is not None and self.mode == "divide":
                winner = self._finish_divided(name, winner, request, left=t0 + limit - time.perf_counter(),
                                              deadline=t0 + limit + simplify + 30.0)
            elif winner is not None and sharing:
                winner = self._finish_shared(name, winner, request, left=t0 + limit - time.perf_counter(),
                                             deadline=t0 + limit + simplify + 30.0)
            elapsed = time.perf_counter() - t0
        if winner is not None and "phase" in winner:
            winner = {**winner, "phases": _phases(self.workers, elapsed, winner, time.thread_time() - parent_cpu)}
        return solution_from(winner, statuses, cores=self.workers, elapsed=elapsed, planner=self.planner)

    def _race(self, request: dict[str, Any], *, deadline: float) -> tuple[dict[str, Any] | None, list[str]]:
        self._request_id += 1
        self._flag.value = 0
        request = {**request, "id": self._request_id}
        for i in range(self.workers):
            self._send(i, request)
        return self._collect(self._request_id, deadline=deadline)

    def _divide(self, request: dict[str, Any], *, seed: int | None, deadline: float
                ) -> tuple[dict[str, Any] | None, list[str]]:
        """The divided search (``divided.py``, ``rounds.py``) on every worker; the first path lifted clear
        of the walls by worker 0 before it is cut into pieces."""
        self._request_id += 1
        rid, name = self._request_id, request["name"]
        self._flag.value = 0
        self._sync.reset()
        search = {"id": rid, "name": name, "op": "search", "start": request["start"], "goal": request["goal"],
                  "resolution": request["resolution"], "time_limit": request["time_limit"],
                  "seed": ompl_seed(self._seed + rid if seed is None else seed), "batch": batch_size(self.workers)}
        sent = time.perf_counter()
        for i in range(self.workers):
            self._send(i, search)
        reports = self._gather(rid, self.workers, deadline=deadline)
        wall = time.perf_counter() - sent
        if any(r is None for r in reports):
            return None, [_DIED]
        done = [r for r in reports if r is not None]
        found = next((r for r in done if r["solved"]), None)  # any that has it: all that do have the same path
        if found is None:
            return None, [done[0]["status"]]
        division = Division.from_reports(done, wall)
        phase = {"search_wall_s": wall, "search_cpu_s": sum(division.cpu_s),
                 "merge_cpu_s": sum(division.serial_cpu_s) / len(done), "lift_wall_s": 0.0, "lift_cpu_s": 0.0}
        first = {"plan_time_s": wall, "checks": sum(division.checks) + done[0]["setup_checks"],
                 "cpu_s": max(division.busy_s), "phase": phase, "division": division, "path": found["path"],
                 "index": None, "solved": True, "status": "first path"}
        if self.workers > 1:
            return first, []  # lifted in pieces, by the workers that finish them (_finish_divided)
        self._request_id += 1
        lift_began = time.perf_counter()
        self._send(0, {"id": self._request_id, "name": name, "op": "lift", "path": found["path"],
                       "resolution": request["resolution"]})
        lifted = self._gather(self._request_id, 1, deadline=deadline)[0]
        if lifted is None:
            return None, ["a worker died during the request"]
        phase.update(lift_wall_s=time.perf_counter() - lift_began, lift_cpu_s=lifted.get("cpu_s", 0.0))
        return {**first, "path": lifted["path"]}, []

    def _finish_whole(self, name: str, first: dict[str, Any], request: dict[str, Any], *, left: float,
                      deadline: float) -> dict[str, Any]:
        """One worker simplifies and proves the whole first path (the divided search on one worker)."""
        self._request_id += 1
        began = time.perf_counter()
        self._send(0, {"id": self._request_id, "name": name, "piece": [Pose(*p) for p in first["path"]],
                       "resolution": request["resolution"], "time_limit": max(1e-3, left),
                       "simplify_time": request["simplify_time"]})
        reports = self._gather(self._request_id, 1, deadline=deadline)
        return {**join_reports(first, reports), "finish": _finish_figures(reports, time.perf_counter() - began)}

    def _finish_shared(self, name: str, first: dict[str, Any], request: dict[str, Any], *, left: float,
                       deadline: float) -> dict[str, Any]:
        """Every worker simplifies and proves one piece of the first path; the pieces joined (or, when
        a piece cannot be proven, the whole path finished by one worker: pieces get half the time left,
        so that finish keeps the other half)."""
        end = time.perf_counter() + left
        path = [Pose(*p) for p in first["path"]]
        radius = self.problems[name].robot.radius()
        pieces = split_path(path, self.workers, radius=radius)
        self._request_id += 1
        self._flag.value = 0
        began = time.perf_counter()
        for i, share in enumerate(simplify_shares(pieces, request["simplify_time"], radius=radius)):
            self._send(i, {"id": self._request_id, "name": name, "piece": pieces[i],
                           "resolution": request["resolution"], "time_limit": max(1e-3, left / 2),
                           "simplify_time": share})
        reports = self._gather(self._request_id, len(pieces), deadline=deadline)
        joined = {**join_reports(first, reports), "finish": _finish_figures(reports, time.perf_counter() - began)}
        left = end - time.perf_counter()
        if joined["solved"] or len(pieces) < 2 or any(r is None for r in reports) or left <= 0:
            return joined
        # A cut pose stays in the answer (no piece may shortcut past it), and one next to a wall can
        # leave its piece unprovable: then one worker finishes the whole path, as the race does.
        self.refinished += 1
        self._request_id += 1
        self._send(0, {"id": self._request_id, "name": name, "piece": path, "resolution": request["resolution"],
                       "time_limit": left, "simplify_time": request["simplify_time"]})
        whole = join_reports(first, self._gather(self._request_id, 1, deadline=deadline))
        spent = max((r.get("cpu_s", 0.0) for r in reports if r), default=0.0)
        return {**whole, "cpu_s": whole["cpu_s"] + spent, "pieces": len(pieces) + 1}

    def _finish_divided(self, name: str, first: dict[str, Any], request: dict[str, Any], *, left: float,
                        deadline: float) -> dict[str, Any]:
        """The divided search's finish: the found path cut into ``FINISH_PIECES_PER_WORKER`` pieces per worker,
        which the workers claim one at a time from a shared counter and lift, simplify and prove
        (``rounds.finish_pieces``); no worker lifts the whole path while the others wait. When a piece cannot
        be proven, one worker finishes the whole path in the time left, as ``share`` does."""
        end = time.perf_counter() + left
        path = [Pose(*p) for p in first["path"]]
        radius = self.problems[name].robot.radius()
        cuts = cut_indices(path, FINISH_PIECES_PER_WORKER * self.workers, radius=radius)
        pieces = [path[a:b + 1] for a, b in zip(cuts, cuts[1:], strict=False)]
        self._request_id += 1
        self._sync.finish_next.value = 0
        began = time.perf_counter()
        message = {"id": self._request_id, "name": name, "op": "finish", "path": first["path"], "cuts": cuts,
                   "resolution": request["resolution"], "time_limit": max(1e-3, left / 2),
                   "simplify_times": simplify_shares(pieces, request["simplify_time"], radius=radius),
                   "planner": self.planner_class}
        for i in range(self.workers):
            self._send(i, message)
        reports = self._gather(self._request_id, self.workers, deadline=deadline)
        figures = _finish_figures(reports, time.perf_counter() - began)
        by_piece: dict[int, dict[str, Any]] = {}
        for r in reports:
            by_piece.update((r or {}).get("pieces", {}))
        ordered = [by_piece.get(i) for i in range(len(pieces))]
        # two pieces meet at a pose both lifted alike; a mismatch would leave an unproven step, so it fails
        if any(a is not None and b is not None and a.get("path") and b.get("path") and a["path"][-1] != b["path"][0]
               for a, b in zip(ordered, ordered[1:], strict=False)):
            ordered[0] = {"solved": False, "status": "pieces did not meet"}
        joined = {**join_reports(first, ordered), "pieces": len(pieces), "finish": figures,
                  "cpu_s": first["cpu_s"] + max(figures["cpu_s"], default=0.0)}
        left = end - time.perf_counter()
        if joined["solved"] or any(r is None for r in reports) or left <= 0:
            return joined
        self.refinished += 1
        self._request_id += 1
        self._send(0, {"id": self._request_id, "name": name, "piece": path, "resolution": request["resolution"],
                       "time_limit": left, "simplify_time": request["simplify_time"], "lift_first": True})
        whole = join_reports(first, self._gather(self._request_id, 1, deadline=deadline))
        return {**whole, "cpu_s": joined["cpu_s"] + whole["cpu_s"] - first["cpu_s"], "pieces": len(pieces) + 1,
                "finish": figures}

    def _gather(self, request_id: int, count: int, *, deadline: float) -> list[dict[str, Any] | None]:
        """Workers 0..count-1's reports on this request, in order; None for one that died or hung."""
        reports: list[dict[str, Any] | None] = [None] * count
        waiting = set(range(count))
        while waiting and (left := deadline - time.perf_counter()) > 0:
            conns: dict[Any, int] = {self._conns[i]: i for i in waiting}
            for item in wait([*conns, *(self._procs[i].sentinel for i in waiting)], timeout=left):
                if item not in conns:
                    continue  # a death shows as EOF on its pipe, after any report it sent
                i = conns[item]
                conn = self._conns[i]
                assert conn is not None
                try:
                    msg: dict[str, Any] = conn.recv()
                except (EOFError, OSError):
                    waiting.discard(i)
                    self._sync.finished.value = 1  # a divided search's survivors stop waiting for it, and report
                    continue
                if msg.get("id") == request_id:
                    reports[i] = msg
                    waiting.discard(i)
        for i in waiting:  # hung: replaced before the next request
            self._procs[i].kill()
        return reports

    def _collect(self, request_id: int, *, deadline: float) -> tuple[dict[str, Any] | None, list[str]]:
        """Every worker's report on this request (or its death); the first with a path wins."""
        waiting = {i for i in range(self.workers)}
        winner: dict[str, Any] | None = None
        statuses: list[str] = []
        while waiting:
            left = deadline - time.perf_counter()
            if left <= 0:
                for i in waiting:  # hung: replaced before the next request
                    self._procs[i].kill()
                statuses.append("a worker hung without reporting")
                break
            conns: dict[Any, int] = {self._conns[i]: i for i in waiting}
            sentinels: dict[Any, int] = {self._procs[i].sentinel: i for i in waiting}
            for item in wait([*conns, *sentinels], timeout=left):
                i = conns[item] if item in conns else sentinels[item]
                conn = self._conns[i]
                assert conn is not None
                if item not in conns and conn.poll():
                    continue  # it died after reporting: the report is read when its pipe comes up
                try:
                    if item not in conns:
                        raise EOFError
                    msg = conn.recv()
                except (EOFError, OSError):
                    waiting.discard(i)
                    statuses.append("a worker died during the request")
                    continue
                if msg.get("id") != request_id:
                    continue  # a late report from a request that timed out
                waiting.discard(i)
                if winner is None and "plan_time_s" in msg:
                    winner = msg
                    self._flag.value = 1
                else:
                    statuses.append(msg["status"])
        return winner, statuses

    def _start(self, i: int) -> None:
        parent, child = self._ctx.Pipe()
        proc = self._ctx.Process(target=_serve, name=f"mp-warm-planner-{i}", daemon=True,
                                 args=(self.problems, PLANNERS[self.planner], ompl_seed(self._seed + i), i,
                                       self._flag, self._sync, child, os.getpid()))
        proc.start()
        child.close()
        self._procs[i], self._conns[i] = proc, parent

    def _await_ready(self, indices: range | list[int]) -> None:
        end = time.perf_counter() + _READY_TIMEOUT_S
        for i in indices:
            conn = self._conns[i]
            assert conn is not None
            if not conn.poll(max(0.0, end - time.perf_counter())):
                raise WorkloadError(f"planner worker {i} did not load its problems within {_READY_TIMEOUT_S:g} s")
            try:
                msg = conn.recv()
            except EOFError:
                raise WorkloadError(f"planner worker {i} died while loading its problems") from None
            if "error" in msg:
                raise WorkloadError(f"planner worker {i}: {msg['error']}")

    def _send(self, i: int, request: dict[str, Any]) -> None:
        """Hand a worker the request; one that died unseen (its pipe broke) is replaced first."""
        try:
            self._conns[i].send(request)  # type: ignore[union-attr]
        except OSError:
            self._replace([i])
            self._conns[i].send(request)  # type: ignore[union-attr]

    def _replace_dead(self) -> None:
        self._replace([i for i, p in enumerate(self._procs) if p is None or not p.is_alive()])

    def _replace(self, dead: list[int]) -> None:
        for i in dead:
            self._discard(i)
            self._start(i)
            self.replaced += 1
        if dead:
            self._await_ready(dead)

    def _discard(self, i: int) -> None:
        proc, conn = self._procs[i], self._conns[i]
        if conn is not None:
            conn.close()
        if proc is not None:
            proc.join(timeout=0)
            if proc.is_alive():
                proc.kill()
            proc.join()
            proc.close()
        self._procs[i], self._conns[i] = None, None

    def close(self) -> None:
        """Stop every worker: a polite None, then a kill for any that outlive the grace period."""
        self._flag.value = 1
        for conn in self._conns:
            if conn is not None:
                try:
                    conn.send(None)
                except OSError:
                    pass
        end = time.perf_counter() + _STOP_GRACE_S
        for proc in self._procs:
            if proc is not None:
                proc.join(timeout=max(0.0, end - time.perf_counter()))
        for i in range(len(self._procs)):
            self._discard(i)


def _finish_figures(reports: list[dict[str, Any] | None], wall: float) -> dict[str, Any]:
    """The finish's wall seconds and, per worker, its CPU and busy seconds and pieces finished."""
    done = [r for r in reports if r is not None]
    return {"wall_s": wall, "cpu_s": tuple(float(r.get("cpu_s", 0.0)) for r in done),
            "busy_s": tuple(float(r.get("wall_s", 0.0)) for r in done),
            "claims": tuple(int(r.get("claims", 1)) for r in done)}


def _phases(workers: int, elapsed: float, report: dict[str, Any], parent_cpu: float) -> Phases:
    phase, finish = report["phase"], report.get("finish") or {"wall_s": 0.0, "cpu_s": (), "busy_s": (), "claims": ()}
    return Phases(workers, elapsed, phase["search_wall_s"], phase["search_cpu_s"], phase["merge_cpu_s"],
                  phase["lift_wall_s"], phase["lift_cpu_s"], finish["wall_s"], finish["cpu_s"], finish["busy_s"],
                  finish["claims"], parent_cpu)


def _serve(problems: Mapping[str, Problem], planner: str, seed: int, index: int, flag: Any, sync: Sync,
           conn: Connection, parent_pid: int) -> None:
    """A warm worker: load every problem once, then answer requests until told to stop."""
    from workloads.motion_planning.search import Search, seed_process  # noqa: PLC0415 (OMPL: workers only)

    try:
        seed_process(seed)
        searches = {name: Search(problem) for name, problem in problems.items()}
        trees = {name: TreeWorker(problem, search.checker) for (name, problem), search in
                 zip(problems.items(), searches.values(), strict=True)}
    except Exception as err:
        conn.send({"error": f"{type(err).__name__}: {err}"})
        return
    conn.send({"ready": index})
    cancelled, first_path = cancel_test(flag, parent_pid), raise_on_first_path(flag)
    while True:
        if not conn.poll(_IDLE_POLL_S):
            if not pid_alive(parent_pid):
                return  # orphaned
            continue
        try:
            request = conn.recv()
        except EOFError:
            return
        if request is None:
            return
        try:
            search = searches[request["name"]]
            op = request.get("op")
            if op is not None:
                report = worker_step(op, request, trees[request["name"]], search, sync, index, cancelled)
            elif "piece" in request:
                report = search.finish(request["piece"], planner=planner, resolution=request["resolution"],
                                       time_limit=request["time_limit"], simplify_time=request["simplify_time"],
                                       lift_first=request.get("lift_first", False))
            else:
                seed = request.get("seed")
                report = search.run(
                    request["start"], request["goal"], planner=planner, resolution=request["resolution"],
                    time_limit=request["time_limit"], simplify_time=request["simplify_time"], cancelled=cancelled,
                    on_first_path=first_path, finish=request["finish"],
                    seed=None if seed is None else ompl_seed(seed + index))
        except Exception as err:  # report, do not hang the parent
            report = {"solved": False, "status": f"worker error: {err}"}
        conn.send({**report, "id": request["id"], "index": index})
