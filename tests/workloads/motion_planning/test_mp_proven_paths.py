"""No answered path passes through a wall, checked by FCL directly and five times finer than planned.

The check here shares nothing with the planner but the meshes it was given: its own fcl
objects, its own interpolation (linear position, shortest-arc slerp, OMPL's SE(3) convention)
and a step of one fifth of the planner's stated resolution, counted as the farthest any robot
point moves. It runs on every shipped problem and on OMPL.app-style problems without a
``[solver]`` section whose plates are thinner than OMPL's default step (1% of the space's
extent) and whose slots turn 90 and 60 degrees apiece, so the bar must roll between them.
"""

from __future__ import annotations

import math
from itertools import pairwise
from pathlib import Path

import fcl
import numpy as np
import pytest

from tests.workloads.motion_planning.mp_support import PROBLEMS
from workloads.motion_planning import Pose, load_problem
from workloads.motion_planning.generate_problems import twisty
from workloads.motion_planning.paper_problems import PAPER_DIR
from workloads.motion_planning.pool import WarmPlanner
from workloads.motion_planning.problem import Problem

FINER = 5


def _object(vertices: np.ndarray, faces: np.ndarray) -> fcl.CollisionObject:
    model = fcl.BVHModel()
    model.beginModel(len(vertices), len(faces))
    model.addSubModel(np.ascontiguousarray(vertices, dtype=float), np.ascontiguousarray(faces, dtype=np.int32))
    model.endModel()
    return fcl.CollisionObject(model, fcl.Transform())


def _slerp(q0: np.ndarray, q1: np.ndarray, t: float) -> np.ndarray:
    angle = math.acos(min(1.0, float(np.dot(q0, q1))))
    if angle < 1e-9:
        return q0
    return (math.sin((1 - t) * angle) * q0 + math.sin(t * angle) * q1) / math.sin(angle)


def colliding_samples(problem: Problem, path: list[Pose], *, step: float) -> tuple[int, int]:
    """(colliding, total) samples along the path, no robot point moving more than ``step`` between two."""
    robot, world = _object(problem.robot.vertices, problem.robot.faces), _object(problem.world.vertices,
                                                                                problem.world.faces)
    radius = float(np.linalg.norm(problem.robot.vertices, axis=1).max())
    request, hits, total = fcl.CollisionRequest(), 0, 0
    for a, b in pairwise(path):
        p0, p1 = np.array([a.x, a.y, a.z]), np.array([b.x, b.y, b.z])
        q0, q1 = (np.array([p.qw, p.qx, p.qy, p.qz]) / math.hypot(p.qw, p.qx, p.qy, p.qz) for p in (a, b))
        if np.dot(q0, q1) < 0:
            q1 = -q1
        turn = 2 * math.acos(min(1.0, float(np.dot(q0, q1))))
        n = max(1, math.ceil((np.linalg.norm(p1 - p0) + radius * turn) / step))
        for i in range(n + 1):
            robot.setTransform(fcl.Transform(_slerp(q0, q1, i / n), p0 + (p1 - p0) * i / n))
            hits += fcl.collide(robot, world, request, fcl.CollisionResult()) > 0
            total += 1
    return hits, total


@pytest.fixture(scope="module")
def generated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ompl_app_style")
    twisty(out, plates=2, name="thin90", thick=0.02, turn=90.0, fraction=None)
    twisty(out, plates=3, name="big60", thick=0.02, turn=60.0, scale=10.0, fraction=None)
    return out


CASES = [("shipped", "easy", 3), ("shipped", "cubicles", 2), ("shipped", "maze", 2), ("shipped", "twisty", 2),
         ("generated", "thin90", 4), ("generated", "big60", 3), ("paper", "apartment", 2), ("paper", "home", 2)]


@pytest.mark.parametrize(("where", "name", "runs"), CASES, ids=[c[1] for c in CASES])
def test_no_answered_path_touches_a_wall(where: str, name: str, runs: int, generated: Path) -> None:
    cfg = {"shipped": PROBLEMS, "generated": generated, "paper": PAPER_DIR}[where] / f"{name}.cfg"
    problem = load_problem(cfg)
    if where == "generated":  # what makes these hard: plates thinner than OMPL's default position step
        diagonal = float(np.linalg.norm(np.subtract(problem.bounds_max, problem.bounds_min)))
        assert 0.02 * (10.0 if name == "big60" else 1.0) < 0.01 * diagonal / 4
    solved = 0
    with WarmPlanner({name: problem}, workers=2, seed=11) as planner:  # the divided search, the default
        for _ in range(runs):
            solution = planner.solve(name, time_limit=60)
            if not solution.solved:
                assert solution.path == ()  # "no path", never a path that was not proven
                continue
            solved += 1
            assert solution.check_resolution < solution.resolution
            hits, total = colliding_samples(problem, list(solution.path), step=solution.resolution / FINER)
            assert (hits, total > len(solution.path)) == (0, True), f"{name}: {hits} of {total} samples collide"
    assert solved >= runs - 1, f"{name}: only {solved} of {runs} solved"


def test_the_independent_check_sees_a_thin_wall(generated: Path) -> None:
    """Straight from start to goal crosses both 0.02-thick plates: the check must say so."""
    problem = load_problem(generated / "thin90.cfg")
    hits, _ = colliding_samples(problem, [problem.start, problem.goal], step=0.004)
    assert hits > 0
