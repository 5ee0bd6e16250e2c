"""One planner instance on one problem, built once and reused for any start and goal.

A :class:`Search` holds the OMPL space, the SimpleSetup and the fcl models of one problem, so a
long-lived worker pays for them once (the warm planner) and a one-shot worker once per solve
(the cold race). Every answer is a path whose segments :class:`Certifier` proved free, or none:

1. plan at the validity resolution (per problem, or per request), OMPL stepping so that no robot
   point moves more than that between two checks;
2. simplify, then prove each segment free (continuous, by clearances, in pieces no shorter than
   ``resolution / CHECK_DIVISOR``, the check resolution the answer states);
3. a segment not proven is re-planned on its own at a quarter of the resolution, and that piece
   proven in turn, up to ``MAX_REPAIR_DEPTH`` levels; what cannot be repaired in the time left
   is answered "no path" (status ``unproven path``).

Runs only inside worker processes: it imports OMPL at the top.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import ompl.base as ob
import ompl.geometric as og
import ompl.util as ou

from workloads.motion_planning.certify import Certifier, as_poses
from workloads.motion_planning.geometry import CollisionChecker, interpolate
from workloads.motion_planning.problem import Pose, Problem, space_extent

CHECK_DIVISOR = 10  # the certifier's finest piece, relative to the planning resolution
MAX_REPAIR_DEPTH = 3
_LIFT_STEPS = 3  # gradient steps to lift a vertex that nearly touches a wall
_REPAIR_SHRINK = 4.0

ou.setLogLevel(ou.LOG_ERROR)


class Search:
    """OMPL set-up and collision models of one problem; :meth:`run` plans one request."""

    def __init__(self, problem: Problem) -> None:
        self.problem = problem
        self.space = ob.SE3StateSpace()
        bounds = ob.RealVectorBounds(3)
        for i in range(3):
            bounds.setLow(i, problem.bounds_min[i])
            bounds.setHigh(i, problem.bounds_max[i])
        self.space.setBounds(bounds)
        self.setup = og.SimpleSetup(self.space)
        # its own simplifier, no goal: a piece's ends stay where they are (SimpleSetup makes one only in solve)
        self.simplifier = og.PathSimplifier(self.setup.getSpaceInformation())
        self.checker = CollisionChecker(problem)
        self.certifier = Certifier(problem)
        checker = self.checker

        def valid(state: Any) -> bool:
            rot = state.rotation()
            return checker.is_free((state.getX(), state.getY(), state.getZ()), (rot.w, rot.x, rot.y, rot.z))

        certifier = self.certifier
        margin = self._margin = [0.0]

        def clear_enough(state: Any) -> bool:
            rot = state.rotation()
            position = np.array((state.getX(), state.getY(), state.getZ()))
            return certifier.clearance(position, np.array((rot.w, rot.x, rot.y, rot.z))) >= margin[0]

        self._valid, self._clear_enough = valid, clear_enough  # OMPL keeps references; so must we
        self.setup.setStateValidityChecker(valid)
        # OMPL steps each SE(3) component by fraction * its extent (the larger count wins), so a
        # fraction of (diagonal + pi * R) bounds any robot point's move per step; see set_resolution.
        self._extent = space_extent(problem)
        self._resolution = -1.0
        self.plan_time_s = self.simplify_time_s = 0.0

    def set_resolution(self, resolution: float) -> None:
        if resolution != self._resolution:
            self.space.setLongestValidSegmentFraction(min(1.0, resolution / self._extent))
            self.space.setup()
            self._resolution = resolution

    def run(self, start: Pose, goal: Pose, *, planner: str, resolution: float, time_limit: float,
            simplify_time: float, cancelled: Callable[[], bool], on_first_path: Callable[[], None],
            finish: bool = True, seed: int | None = None) -> dict[str, Any]:
        """Plan, simplify, prove; a report dict (``solved``, ``status``, ``path``, timings, counts).

        ``planner`` is a class name in ``ompl.geometric`` (``RRTConnect``, ...). With
        ``finish=False`` the first path is reported as planned (status ``first path``), for the
        parent to share its simplifying and proving out among the workers (:meth:`finish`).
        ``seed`` (OMPL's range) makes the search repeatable: see :func:`seed_request`.
        """
        self.checker.checks = 0
        self.certifier.queries = 0
        deadline, cpu = _Clock(time_limit), time.process_time()
        found = self._plan(start, goal, planner=planner, resolution=resolution, ptc=_ptc(deadline, cancelled),
                           seed=seed)
        if found is None or cancelled():  # another worker's path came first: do not simplify ours too
            status = "cancelled" if cancelled() else str(self.setup.getLastPlannerStatus()).lower()
            return {"solved": False, "status": status}
        on_first_path()
        found = self.lift(found, resolution)
        first = {"plan_time_s": self.plan_time_s, "checks": self.checker.checks,
                 "cpu_s": time.process_time() - cpu}
        if not finish:
            return {**first, "solved": True, "status": "first path", "path": _tuples(found)}
        done = self.finish(found, planner=planner, resolution=resolution, time_limit=deadline.left(),
                           simplify_time=simplify_time)
        return {**first, **done, "cpu_s": first["cpu_s"] + done["cpu_s"]}

    def finish(self, path: list[Pose], *, planner: str, resolution: float, time_limit: float,
               simplify_time: float, lift_first: bool = False) -> dict[str, Any]:
        """Simplify a planned path (or a piece of one) with clearance, then prove and repair it.

        ``cpu_s`` in the report (and in :meth:`run`'s, up to the first path and then for the whole)
        is this process's CPU time: work that other jobs' load does not stretch, unlike wall time.
        ``lift_first``: the path's inner vertices are lifted here first (a piece of a found path that no
        one worker lifted whole; its ends were lifted by :meth:`lift_at`).
        """
        self.certifier.queries = 0
        deadline, cpu, began = _Clock(time_limit), time.process_time(), time.perf_counter()
        self.set_resolution(resolution)
        if lift_first:
            path = self.lift(path, resolution)
        simplified = self.lift(self._simplify(self._geometric(path), simplify_time, resolution), resolution)
        floor = resolution / CHECK_DIVISOR
        proven, repairs = self._prove(simplified, planner=planner, resolution=resolution, floor=floor, depth=0,
                                      deadline=deadline)
        report = {"simplify_time_s": self.simplify_time_s, "repairs": repairs, "cpu_s": time.process_time() - cpu,
                  "clearance_queries": self.certifier.queries, "resolution": resolution, "check_resolution": floor,
                  "wall_s": time.perf_counter() - began}
        if proven is None:
            return {**report, "solved": False, "status": "unproven path"}
        return {**report, "solved": True, "status": "exact solution", "path": _tuples(proven)}

    def _plan(self, start: Pose, goal: Pose, *, planner: str, resolution: float, ptc: Any,
              straight: bool = True, seed: int | None = None) -> list[Pose] | None:
        """The planner's path, or the straight move when it is free and ``straight`` (not in a repair:
        there the straight move is the segment that could not be proven)."""
        self.set_resolution(resolution)
        self.setup.clear()
        a, b = self.space.allocState(), self.space.allocState()
        _set_state(a, start)
        _set_state(b, goal)
        self.setup.setStartAndGoalStates(a, b)
        si, started = self.setup.getSpaceInformation(), time.perf_counter()
        if straight and si.isValid(a) and si.checkMotion(a, b):  # the straight move is free: no search needed
            self.plan_time_s = time.perf_counter() - started
            return [start, goal]
        if seed is not None:  # right before the planner and its sampler are made: nothing else draws a seed
            seed_request(seed)
        self.setup.setPlanner(getattr(og, planner)(si))
        self.setup.solve(ptc)
        self.plan_time_s = time.perf_counter() - started
        if not self.setup.haveExactSolutionPath():
            return None
        return as_poses(self.setup.getSolutionPath().getStates())

    def lift(self, path: list[Pose], resolution: float) -> list[Pose]:
        """The path with its inner vertices that nearly touch a wall pushed out to half a step of clearance.

        The planner's vertices need only be valid, simplifying keeps them, and its subdividing puts new
        vertices halfway between checked poses, where the clearance can be near nothing: a vertex that
        grazes a wall leaves its segments unprovable, and then each is re-planned (0.3-2 s a repair; one
        request in ten on the maze, some answered "no path"). A vertex under ``resolution / 2`` of
        clearance is moved (position only) along its clearance's gradient, as long as both of its
        segments stay valid; one that cannot be lifted so stays where it was. The ends never move.
        Used on the first path (so the poses where a shared request is cut are lifted too) and on
        every simplified path before it is proven.
        """
        self.set_resolution(resolution)
        out = list(path)
        for i in range(1, len(out) - 1):
            lifted = self._lifted(out[i - 1], out[i], out[i + 1], margin=resolution / 2)
            if lifted is not None:
                out[i] = lifted
        return out

    def lift_at(self, path: list[Pose], i: int, resolution: float) -> Pose:
        """path[i] lifted against its neighbours as found (not as lifted): the pose where two pieces of a
        divided finish meet, which both pieces' workers compute alike; the path's ends never move."""
        if i <= 0 or i >= len(path) - 1:
            return path[i]
        self.set_resolution(resolution)
        lifted = self._lifted(path[i - 1], path[i], path[i + 1], margin=resolution / 2)
        return path[i] if lifted is None else lifted

    def _lifted(self, before: Pose, pose: Pose, after: Pose, *, margin: float) -> Pose | None:
        clearance, q = self.certifier.clearance, pose.quaternion()
        position = pose.position()
        clear = clearance(position, q)
        if clear >= margin:
            return None
        h = margin / 4
        for _ in range(_LIFT_STEPS):
            grad = np.array([clearance(position + h * e, q) - clearance(position - h * e, q) for e in np.eye(3)])
            norm = float(np.linalg.norm(grad))
            if norm == 0.0:
                return None  # deep in a wall, or flat all round: nothing says which way is out
            position = position + grad / norm * (margin - clear + h)
            clear = clearance(position, q)
            if clear >= margin:
                break
        else:
            return None
        moved = Pose(float(position[0]), float(position[1]), float(position[2]), pose.qx, pose.qy, pose.qz, pose.qw)
        si = self.setup.getSpaceInformation()
        a, b, c = self.space.allocState(), self.space.allocState(), self.space.allocState()
        for state, p in ((a, before), (b, moved), (c, after)):
            _set_state(state, p)
        return moved if si.checkMotion(a, b) and si.checkMotion(b, c) else None

    def _bend(self, a: Pose, b: Pose, *, resolution: float, floor: float) -> list[Pose] | None:
        """[m, b]: the segment's pose nearest a wall, lifted to half a step of clearance, when both
        halves then prove; None otherwise. A segment the planner left (checked for validity only, not
        for clearance) can graze a wall between two free ends; this costs a few clearance queries
        where a re-plan of the segment costs 0.3-2 s."""
        inner = interpolate(a, b, max_step=resolution, radius=self.certifier.radius, min_steps=2)[1:-1]
        clear, i = min((self.certifier.clearance(*pose), i) for i, pose in enumerate(inner))
        nearest = Pose.from_arrays(*inner[i])
        # clear enough already, a bend there may prove where the straight segment did not; else lift it
        margin = resolution / 2
        moved = nearest if clear >= margin else self._lifted(a, nearest, b, margin=margin)
        if moved is None or not (self.certifier.segment_is_free(a, moved, floor=floor)
                                 and self.certifier.segment_is_free(moved, b, floor=floor)):
            return None
        return [moved, b]

    def _geometric(self, poses: list[Pose]) -> Any:
        path = og.PathGeometric(self.setup.getSpaceInformation())
        state = self.space.allocState()
        for pose in poses:
            _set_state(state, pose)
            path.append(state)  # copied
        return path

    def _simplify(self, path: Any, seconds: float, resolution: float) -> list[Pose]:
        """Shortcut the solution, accepting only shortcuts that keep half a step of clearance.

        Plain shortcutting pulls a path onto the obstacles, as close as the step allows, and such
        a path cannot be proven. With a clearance of half a step at every checked pose, a
        shortcut is proven by the very checks that accepted it (clearances of two neighbours add
        up to a step). Vertices the planner placed keep their plain validity.
        """
        self._margin[0] = resolution / 2
        self.setup.setStateValidityChecker(self._clear_enough)
        started = time.perf_counter()
        try:
            self.simplifier.simplify(path, seconds, atLeastOnce=False)  # the budget holds
        finally:
            self.simplify_time_s = time.perf_counter() - started
            self.setup.setStateValidityChecker(self._valid)
        return as_poses(path.getStates())

    def _prove(self, path: list[Pose], *, planner: str, resolution: float, floor: float, depth: int,
               deadline: _Clock) -> tuple[list[Pose] | None, int]:
        """The path with every unproven segment replaced by a proven re-plan; None when that fails."""
        repairs = 0
        out = [path[0]]
        for a, b in zip(path, path[1:], strict=False):
            if self.certifier.segment_is_free(a, b, floor=floor):
                out.append(b)
                continue
            bent = self._bend(a, b, resolution=resolution, floor=floor)
            if bent is not None:  # a segment that grazes a wall midway, bent away from it: no re-plan
                out += bent
                continue
            if depth >= MAX_REPAIR_DEPTH or deadline.left() <= 0:
                return None, repairs
            repairs += 1
            finer = resolution / _REPAIR_SHRINK
            piece = self._plan(a, b, planner=planner, resolution=finer, ptc=_ptc(deadline, lambda: False),
                               straight=False)
            if piece is None:
                return None, repairs
            piece = self.lift(self._simplify(self._geometric(piece), min(0.2, max(0.0, deadline.left())), finer),
                              finer)
            fixed, more = self._prove(piece, planner=planner, resolution=finer, floor=floor,
                                      depth=depth + 1, deadline=deadline)
            repairs += more
            if fixed is None:
                return None, repairs
            out += fixed[1:]
        if len(path) == 1 and not self.certifier.segment_is_free(path[0], path[0], floor=floor):
            return None, repairs
        return out, repairs


def _set_state(state: Any, pose: Pose) -> None:
    state.setXYZ(pose.x, pose.y, pose.z)
    rot = state.rotation()
    rot.w, rot.x, rot.y, rot.z = (float(v) for v in pose.quaternion())


def _tuples(path: list[Pose]) -> list[tuple[float, ...]]:
    return [(p.x, p.y, p.z, p.qx, p.qy, p.qz, p.qw) for p in path]


def seed_process(seed: int) -> None:
    """Seed OMPL's generator; only the first seed in a process counts (OMPL ignores later ones)."""
    global _SEEDED
    if not _SEEDED:
        ou.RNG.setSeed(seed)
        _SEEDED = True


_SEEDED = False


def seed_request(seed: int) -> None:
    """Seed the random generators OMPL makes from now on: the request's planner and its sampler.

    A :class:`Search` makes a new planner for every request, and reseeds just before, so a
    request that names its seed draws the same samples in any warm worker, whatever that worker
    did before (the simplifier's generator, made once per worker, is not reseeded: simplifying
    is bounded by time anyway).
    OMPL reseeds but logs an error after its first seed; that line is silenced here.
    """
    level = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)
    try:
        ou.RNG.setSeed(seed)
    finally:
        ou.setLogLevel(level)


class _Clock:
    def __init__(self, seconds: float) -> None:
        self._end = time.perf_counter() + seconds

    def left(self) -> float:
        return self._end - time.perf_counter()


def _ptc(deadline: _Clock, cancelled: Callable[[], bool]) -> Any:
    left = max(1e-3, deadline.left())
    if not math.isfinite(left):
        left = 1e9
    return ob.plannerOrTerminationCondition(ob.timedPlannerTerminationCondition(left),
                                            ob.PlannerTerminationCondition(cancelled))
